"""Who is calling: ``current_user`` reads ``Authorization: Bearer TOKEN`` and answers 401 without a valid one.

``MaybeUser`` (the caller if a valid token came, else None) serves the routes that charge quotas until every
route requires a user; a request without one is charged to nobody.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request
from starlette.exceptions import HTTPException

from curvefm.access import User


def current_user(request: Request) -> User:
    user = optional_user(request)
    if user is None:
        detail = "a valid token is needed: send 'Authorization: Bearer TOKEN' ('curvefm users add NAME' makes one)"
        raise HTTPException(401, detail=detail, headers={"WWW-Authenticate": "Bearer"})
    return user


def optional_user(request: Request) -> User | None:
    scheme, _, token = request.headers.get("authorization", "").partition(" ")
    return request.app.state.services.users.authenticate(token.strip()) if scheme.lower() == "bearer" else None


CurrentUser = Annotated[User, Depends(current_user)]
MaybeUser = Annotated[User | None, Depends(optional_user)]
