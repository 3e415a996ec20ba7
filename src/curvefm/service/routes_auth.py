"""``/auth``: the web page trades the token of its login URL for a cookie, asks who is logged in, logs out."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Request, Response

from curvefm.access import User
from curvefm.service.auth import (
    AUTHENTICATED,
    BEARER,
    CurrentUser,
    bearer_user,
    clear_login_cookie,
    set_login_cookie,
)
from curvefm.service.deps import ServicesDep
from curvefm.service.errors import error_responses
from curvefm.service.models import UserInfo

router = APIRouter(tags=["auth"], responses=error_responses(401, 403))


@router.post("/auth/login", response_model=UserInfo, dependencies=[Depends(BEARER)], responses=error_responses(507))
def login(request: Request, response: Response, user: Annotated[User, Depends(bearer_user)], services: ServicesDep):
    """Trade a bearer token for the login cookie (HttpOnly, SameSite=Strict): what the page does with the
    ``?token=`` of the login URL. The cookie ends when it expires, or when the token is rotated or its user
    removed."""
    set_login_cookie(request, response, services.logins.issue(user), services.settings.login_ttl_s)
    return UserInfo(name=user.name, admin=user.admin)


@router.post("/auth/logout", status_code=204, dependencies=AUTHENTICATED, responses=error_responses(507))
def logout(request: Request, services: ServicesDep, user: CurrentUser) -> Response:
    """End your web page logins, in every browser (their cookies are refused from now on; your token stays
    good), and remove the login cookie from this browser."""
    services.users.end_logins(user.name)
    response = Response(status_code=204)
    clear_login_cookie(request, response)
    return response


@router.get("/auth/me", response_model=UserInfo, dependencies=AUTHENTICATED)
def me(user: CurrentUser) -> UserInfo:
    return UserInfo(name=user.name, admin=user.admin)
