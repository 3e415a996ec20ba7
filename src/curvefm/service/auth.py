"""Who is asking: :func:`current_user`, the dependency of every route but ``GET /health`` and the sign-in's own
(``/auth/methods``, ``/auth/oidc/*``; the UI's static files are not routes), checked for state-changing requests
before their body is read (:class:`CredentialsFirst`).

Credentials, the first found wins:

* ``Authorization: Bearer TOKEN``, for programs (``curvefm users add NAME`` prints a token). A wrong one is a
  401 even when a login cookie comes with it.
* the login cookie (:mod:`curvefm.service.login`) that ``POST /auth/login`` gives the web page for a token, or
  single sign-on for a sign-in at the lab's OpenID Connect provider (:mod:`curvefm.service.oidc`). A
  browser attaches it to requests by itself, so a state-changing request (POST, PUT, PATCH, DELETE) that relies
  on it must come with an ``Origin`` equal to the service's own (the scheme and Host it was reached at): a page
  of another site gets 403 (SameSite=Strict already keeps the cookie off cross-site requests in today's
  browsers; the check does not rely on that). Bearer requests need no Origin: no browser adds a token by itself.
"""

from __future__ import annotations

from typing import Annotated
from urllib.parse import urlsplit

from fastapi import Depends, Request, Response
from fastapi.security import HTTPBearer

from curvefm.access import User
from curvefm.errors import CurvefmError, Forbidden, Unauthenticated
from curvefm.service.errors import project_error_response

SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
DEFAULT_PORTS = {"http": 80, "https": 443}
COOKIE_PREFIX = "curvefm_login_"
LOCAL_ADMIN = "admin"
"""The user ``curvefm serve`` creates when a data directory has none, and the owner of the demo session."""
SHOWN_ORIGIN_CHARS = 100
HOW_TO_LOG_IN = (
    "send 'Authorization: Bearer TOKEN' ('curvefm users add NAME' makes a user and prints its token), or open the "
    "login URL that 'curvefm serve' printed (http://HOST:PORT/?token=...)"
)
BEARER = HTTPBearer(auto_error=False, description="a token from 'curvefm users add NAME'")
"""For the OpenAPI schema (the Authorize button of /docs); :func:`current_user` reads the header itself."""


async def current_user(request: Request) -> User:
    """The dependency: :func:`request_user`, run on the event loop (a ``stat`` and a hash; a plain function
    dependency would cost a hand-off to a worker thread on every request)."""
    return request_user(request)


def request_user(request: Request) -> User:
    """The user behind the request's credentials; :class:`Unauthenticated` (401) without valid ones,
    :class:`Forbidden` (403) for a cookie-authenticated write from another origin."""
    user = getattr(request.state, "user", None)
    if user is None:
        user = request.state.user = _authenticate(request)
    return user


CurrentUser = Annotated[User, Depends(current_user)]
AUTHENTICATED = [Depends(current_user), Depends(BEARER)]
"""The dependencies of a router whose routes all need a user."""


class CredentialsFirst:
    """Checks the credentials of a state-changing request at its headers, before its body is read: the routes'
    dependencies run only after FastAPI has parsed the body, and an anonymous upload would be spooled first."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] == "http" and scope["method"] not in SAFE_METHODS:
            request = Request(scope)
            try:
                request_user(request)  # remembered in the request's state for the route
            except CurvefmError as exc:
                await project_error_response(request, exc)(scope, receive, send)
                return
        await self.app(scope, receive, send)


def bearer_user(request: Request) -> User:
    """The user of the request's bearer token (no cookie counts): what ``POST /auth/login`` trades for one."""
    header = request.headers.get("authorization")
    if header is None:
        raise Unauthenticated(f"logging in needs a token: {HOW_TO_LOG_IN}")
    return _token_user(request, header)


def _authenticate(request: Request) -> User:
    header = request.headers.get("authorization")
    if header is not None:
        return _token_user(request, header)
    cookie = request.cookies.get(cookie_name(request))
    if cookie is None:
        raise Unauthenticated(f"this request needs credentials: {HOW_TO_LOG_IN}")
    user = request.app.state.services.logins.verify(cookie)
    if user is None:
        raise Unauthenticated(
            "the login has expired, or its user's token was changed or removed; open the login URL again "
            "(an admin makes a new token with 'curvefm users token NAME --rotate')"
        )
    check_origin(request)
    return user


def identify(request: Request) -> User | None:
    """The user the request's credential belongs to, or None, without the checks that refuse a request (the
    origin of a cookie write): what the rate limit counts requests against."""
    services = request.app.state.services
    header = request.headers.get("authorization")
    if header is not None:
        scheme, _, token = header.partition(" ")
        return services.users.authenticate(token.strip()) if scheme.lower() == "bearer" else None
    cookie = request.cookies.get(cookie_name(request))
    return None if cookie is None else services.logins.verify(cookie)


def _token_user(request: Request, header: str) -> User:
    scheme, _, token = header.partition(" ")
    if scheme.lower() != "bearer" or not token.strip():
        raise Unauthenticated(f"the Authorization header must be 'Bearer TOKEN': {HOW_TO_LOG_IN}")
    user = request.app.state.services.users.authenticate(token.strip())
    if user is None:
        raise Unauthenticated("the token is not valid: it is wrong, or was rotated, or its user was removed")
    return user


def check_origin(request: Request) -> None:
    """A cookie-authenticated write must say it comes from a page of this service."""
    if request.method in SAFE_METHODS:
        return
    origin = request.headers.get("origin")
    own = own_origin(request)
    if origin is None or _origin_key(origin) != _origin_key(own):
        shown = "none" if origin is None else repr(origin[:SHOWN_ORIGIN_CHARS])
        raise Forbidden(
            f"a {request.method} authenticated by the login cookie must come from this service's own pages "
            f"(Origin {own}); the request's Origin is {shown}. Programs send 'Authorization: Bearer TOKEN' instead"
        )


def own_origin(request: Request) -> str:
    """``scheme://host[:port]`` as the client addressed this service (its Host header)."""
    return f"{request.url.scheme}://{request.headers.get('host', request.url.netloc)}"


def _origin_key(origin: str) -> tuple[str, str, int] | None:
    """(scheme, host, port) with the default port filled in; None for what is no origin ("null", garbage)."""
    try:
        parts = urlsplit(origin)
        port = parts.port or DEFAULT_PORTS.get(parts.scheme)
    except ValueError:
        return None
    if not parts.hostname or port is None:
        return None
    return parts.scheme, parts.hostname, port


def cookie_name(request: Request) -> str:
    """One cookie name per port: browsers share cookies across the ports of a host, so two services on one
    machine (a demo and a lab server) would otherwise log each other out."""
    key = _origin_key(own_origin(request))
    return f"{COOKIE_PREFIX}{key[2] if key else 0}"


def set_login_cookie(request: Request, response: Response, value: str, max_age_s: float) -> None:
    response.set_cookie(
        cookie_name(request),
        value,
        max_age=int(max_age_s),
        path="/",
        httponly=True,
        samesite="strict",
        secure=request.url.scheme == "https",
    )


def clear_login_cookie(request: Request, response: Response) -> None:
    response.delete_cookie(cookie_name(request), path="/", httponly=True, samesite="strict")
