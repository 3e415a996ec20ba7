"""How to get what is missing, in HTTP terms, added to the messages of the core's errors (which name what is
missing without saying how a client of this API obtains it)."""

from __future__ import annotations

import json
from typing import cast

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse

from curvefm.errors import CurvefmError
from curvefm.service.errors import error_response
from curvefm.session import BasisNeed, MissingBasis, UnknownSession, UnknownShape


def with_hint(error: CurvefmError) -> str:
    """``error``'s message with what to request next (other errors' messages unchanged)."""
    if isinstance(error, MissingBasis):
        return "; ".join(f"{need.describe()}; {basis_request(need)}" for need in error.needs)
    if isinstance(error, UnknownShape):
        return f"{error.message}; upload it with POST /shapes"
    if isinstance(error, UnknownSession):
        # the same words for a private session of someone else's: a 404 does not tell which ids exist
        return (
            f"{error.message} that you may open: it does not exist, or it is private (its owner has not shared it "
            "with you); GET /sessions lists the sessions you may open"
        )
    return error.message


def basis_request(need: BasisNeed) -> str:
    body = json.dumps({"k": need.k, "plugin": need.plugin, "params": need.params})
    return f"request it with POST /shapes/{need.mesh_id}/bases {body} and wait for the job to finish"


def install_hints(app: FastAPI) -> None:
    async def hinted(request: Request, exc: Exception) -> JSONResponse:
        error = cast(CurvefmError, exc)  # registered for the CurvefmError subclasses below only
        return error_response(error, with_hint(error))

    for error_type in (MissingBasis, UnknownShape, UnknownSession):
        app.add_exception_handler(error_type, hinted)
