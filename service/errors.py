"""Errors a request can cause, and their JSON 4xx bodies: ``{"error": kind, "detail": message, ...}``."""

from __future__ import annotations

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from curvefm import registry
from curvefm.errors import CurvefmError
from curvefm.registry import Plugin

STATUS = {"invalid": 400, "not_found": 404, "conflict": 409, "too_large": 413}


class UnknownPlugin(CurvefmError):
    def __init__(self, kind: str, name: str):
        self.available = registry.names(kind)
        super().__init__(f"unknown {kind} '{name}'; installed {kind}s: {', '.join(self.available) or 'none'}")


def require_plugin(kind: str, name: str) -> Plugin:
    """The plugin, or an error listing the installed ones. (``registry.get`` caches what it loaded; listing
    entry points costs tens of milliseconds, so it is done only when the name is unknown.)"""
    try:
        return registry.get(kind, name)
    except CurvefmError:
        if name in registry.names(kind):
            raise
        raise UnknownPlugin(kind, name) from None


def error_response(exc: CurvefmError) -> JSONResponse:
    body = {"error": exc.kind, "detail": exc.message}
    if isinstance(exc, UnknownPlugin):
        body["available"] = exc.available
    return JSONResponse(body, status_code=STATUS.get(exc.kind, 400))


def install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(CurvefmError)
    async def curvefm_error(request: Request, exc: CurvefmError) -> JSONResponse:
        return error_response(exc)

    @app.exception_handler(RequestValidationError)
    async def validation_error(request: Request, exc: RequestValidationError) -> JSONResponse:
        fields = [{"field": ".".join(str(part) for part in e["loc"]), "problem": e["msg"]} for e in exc.errors()]
        detail = "; ".join(f"{f['field']}: {f['problem']}" for f in fields)
        return JSONResponse({"error": "invalid", "detail": detail, "fields": fields}, status_code=422)
