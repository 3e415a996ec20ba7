"""``/auth``: the web page trades the token of its login URL for a cookie, or signs in at the lab's OpenID Connect
provider (:mod:`curvefm.service.oidc`); asks who is logged in; makes a new token for scripts; logs out."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Request, Response
from fastapi.responses import RedirectResponse
from starlette.concurrency import run_in_threadpool

from curvefm.access import User
from curvefm.errors import CurvefmError, NotFound
from curvefm.service.auth import (
    AUTHENTICATED,
    BEARER,
    CurrentUser,
    bearer_user,
    clear_login_cookie,
    cookie_name,
    set_login_cookie,
)
from curvefm.service.deps import Services, ServicesDep
from curvefm.service.errors import error_responses
from curvefm.service.models import LoginMethods, NewToken, SingleSignOnInfo, UserInfo
from curvefm.service.oidc import PATHS, SingleSignOn, sign_in_failed
from curvefm.service.settings import env_name

router = APIRouter(tags=["auth"], responses=error_responses(401, 403))
SIGN_IN_ERRORS = error_responses(
    404,
    503,
    described={
        404: "single sign-on is not configured (CURVEFM_OIDC_ISSUER)",
        503: "the provider does not answer, or answers as configured wrongly",
    },
)
"""A sign-in's errors are a page saying why for a browser (Accept: text/html), else these JSON bodies."""
NOT_CONFIGURED = (
    f"single sign-on is not configured here ({env_name('oidc_issuer')}, {env_name('oidc_client_id')} and "
    f"{env_name('oidc_client_secret')}); log in with a token"
)


@router.post("/auth/login", response_model=UserInfo, dependencies=[Depends(BEARER)], responses=error_responses(507))
def login(request: Request, response: Response, user: Annotated[User, Depends(bearer_user)], services: ServicesDep):
    """Trade a bearer token for the login cookie (HttpOnly, SameSite=Strict): what the page does with the
    ``?token=`` of the login URL. The cookie ends when it expires, or when the token is rotated or its user
    removed."""
    set_login_cookie(request, response, services.logins.issue(user), services.settings.login_ttl_s)
    return UserInfo(name=user.name, admin=user.admin)


@router.get("/auth/methods", response_model=LoginMethods)
def login_methods(services: ServicesDep) -> LoginMethods:
    """How one may log in besides a token (public: the login page asks before anyone is logged in)."""
    if services.sso is None:
        return LoginMethods(single_sign_on=None)
    label = services.settings.oidc_label
    return LoginMethods(single_sign_on=SingleSignOnInfo(label=label, login_url=f"{PATHS}/login"))


@router.get(
    f"{PATHS}/login",
    status_code=302,
    response_class=RedirectResponse,
    responses={302: {"description": "to the provider's sign-in"}, **SIGN_IN_ERRORS},
)
async def oidc_login(request: Request, services: ServicesDep) -> Response:
    """Sign in at the lab's OpenID Connect provider (public): a redirect there, with a fresh state, nonce and
    PKCE challenge; the provider sends the browser back to ``/auth/oidc/callback``."""
    sso = _configured(services)
    try:
        return await sso.redirect(request)
    except CurvefmError as exc:
        return sign_in_failed(request, exc)


@router.get(
    f"{PATHS}/callback",
    name="oidc_callback",
    status_code=303,
    response_class=RedirectResponse,
    responses={
        303: {"description": "signed in: the login cookie, and to the web page"},
        **SIGN_IN_ERRORS,
        **error_responses(
            400,
            described={400: "not a sign-in this browser began here, or it took longer than CURVEFM_OIDC_LOGIN_TIMEOUT"},
        ),
    },
)
async def oidc_callback(request: Request, services: ServicesDep) -> Response:
    """Where the provider sends the browser back (public), with ``code`` and ``state``, or ``error`` and
    ``error_description`` (OAuth 2.0, RFC 6749 4.1.2): the sign-in is checked, the person's user found (made at
    their first sign-in, not an admin), and the browser gets the login cookie and goes to the web page."""
    sso = _configured(services)
    try:
        issuer, subject, name = await sso.identity(request)
        user = await run_in_threadpool(_sign_in, services, issuer, subject, name)
    except CurvefmError as exc:
        return sign_in_failed(request, exc)
    response = RedirectResponse("/", status_code=303)
    set_login_cookie(
        request, response, await run_in_threadpool(services.logins.issue, user), services.settings.login_ttl_s
    )
    return response


@router.post("/auth/token", response_model=NewToken, dependencies=AUTHENTICATED, responses=error_responses(507))
def new_token(request: Request, response: Response, services: ServicesDep, user: CurrentUser) -> NewToken:
    """A new bearer token of yours, for scripts (``Authorization: Bearer TOKEN``), shown only in this answer. Your
    token so far stops working, and with it your web page logins elsewhere; this browser's login cookie is
    renewed."""
    token = services.users.rotate(user.name)
    services.audit.record(user.name, "user.token", user.name)
    if cookie_name(request) in request.cookies:
        set_login_cookie(request, response, services.logins.issue(user), services.settings.login_ttl_s)
    response.headers["Cache-Control"] = "no-store"
    return NewToken(name=user.name, token=token)


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


def _configured(services: Services) -> SingleSignOn:
    if services.sso is None:
        raise NotFound(NOT_CONFIGURED)
    return services.sso


def _sign_in(services: Services, issuer: str, subject: str, name: str) -> User:
    user, made = services.users.sign_in(issuer, subject, name)
    if made:
        services.audit.record(user.name, "user.add", user.name, {"single_sign_on": issuer})
    return user
