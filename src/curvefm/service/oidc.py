"""Single sign-on with OpenID Connect: the authorization code flow with PKCE, as a relying party built on Authlib's
Starlette client.

``GET /auth/oidc/login`` sends the browser to the provider (its endpoints from
``ISSUER/.well-known/openid-configuration``, read once per process) with a fresh state, nonce and PKCE (S256)
challenge, which wait in a signed cookie of the ``/auth/oidc`` paths only (:class:`SignInState`: Starlette's
session middleware, keyed from the data directory's signing key, so any API process can finish a sign-in another
began). ``GET /auth/oidc/callback`` checks the state, trades the code (with the verifier and the client secret) for
tokens, and verifies the ID token: its signature against the provider's JWKS, its issuer, audience (our client id),
expiry and nonce. The identity (issuer, subject) then signs in as its user (:meth:`curvefm.access.Users.sign_in`,
made at its first sign-in) and the browser gets the same login cookie as a token login.

Whatever goes wrong is a :class:`~curvefm.errors.CurvefmError` saying what: 400 for a sign-in this browser did not
begin here (or that took longer than ``CURVEFM_OIDC_LOGIN_TIMEOUT``), 401 for a refusal (by the provider, or of its
ID token), 503 for a provider that does not answer or is configured wrongly. The client secret appears in none.
"""

from __future__ import annotations

import hashlib
import hmac
import html
import logging
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import httpx2
from authlib.integrations.base_client import MismatchingStateError, OAuthError
from authlib.integrations.starlette_client import OAuth
from fastapi import Request
from fastapi.responses import HTMLResponse, Response
from joserfc.errors import JoseError
from starlette.middleware.sessions import SessionMiddleware

from curvefm.errors import CurvefmError, InvalidInput, Unauthenticated, Unavailable, shown
from curvefm.service.errors import error_response, status_of
from curvefm.service.settings import Settings, env_name

log = logging.getLogger("curvefm.service")

PATHS = "/auth/oidc"
STATE_COOKIE = "curvefm_oidc"
MAX_SUBJECT_CHARS = 255  # OpenID Connect Core 2: "It MUST NOT exceed 255 ASCII characters in length"
CLOCK_LEEWAY_S = 60  # between our clock and the provider's, for the ID token's times
FAILED_PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Signing in failed - curvefm</title>
<link rel="stylesheet" href="/style.css"></head>
<body><div class="banner" role="alert"><p id="sign-in-failed">Signing in failed: {message}</p>
<p><a href="/">Back to curvefm</a></p></div></body></html>
"""


class SingleSignOn:
    """The provider of ``settings`` (``oidc_issuer`` and the client's id and secret) as Authlib's client."""

    def __init__(self, settings: Settings):
        assert settings.oidc_issuer and settings.oidc_client_id and settings.oidc_client_secret
        self.issuer, self.name_claim = settings.oidc_issuer, settings.oidc_name_claim
        self.login_timeout_s = settings.oidc_login_timeout_s
        scopes = settings.oidc_scopes.split()
        self.client: Any = OAuth().register(
            "oidc",
            client_id=settings.oidc_client_id,
            client_secret=settings.oidc_client_secret.get_secret_value(),
            server_metadata_url=f"{self.issuer.rstrip('/')}/.well-known/openid-configuration",
            client_kwargs={
                "scope": " ".join(scopes if "openid" in scopes else ["openid", *scopes]),
                "code_challenge_method": "S256",
                "timeout": settings.oidc_timeout_s,
            },
        )

    async def redirect(self, request: Request) -> Response:
        """The answer that sends the browser to the provider's sign-in. A browser has one sign-in under way, its
        latest: the state cookie stays small however often one starts."""
        with provider_errors(self):
            await self._metadata()
            request.session.clear()
            return await self.client.authorize_redirect(request, str(request.url_for("oidc_callback")))

    async def identity(self, request: Request) -> tuple[str, str, str]:
        """(issuer, subject, wanted user name) of the person the provider sent back with this request."""
        if not request.query_params.get("state"):
            raise InvalidInput("this is where the provider sends a person back after signing in; start at /")
        with provider_errors(self):
            await self._metadata()
            token = await self.client.authorize_access_token(request, leeway=CLOCK_LEEWAY_S)
            claims = token.get("userinfo")
            if claims is None:
                raise Unauthenticated(f"the provider {self.issuer} answered without an ID token")
            subject = claims["sub"]
            if not isinstance(subject, str) or not 0 < len(subject) <= MAX_SUBJECT_CHARS:
                raise Unauthenticated(f"the provider {self.issuer} gave no subject of 1 to 255 characters")
            if not any(claims.get(name) for name in (self.name_claim, "email")):
                claims = {**await self._userinfo(token, subject), **claims}
        return self.issuer, subject, self._wanted_name(claims)

    async def _metadata(self) -> None:
        metadata = await self.client.load_server_metadata()
        if metadata.get("issuer") != self.issuer:
            raise Unavailable(
                f"the provider at {env_name('oidc_issuer')} says its issuer is {shown(metadata.get('issuer'))!r}: "
                "single sign-on needs that exact URL as the setting (an administrator's fix)"
            )

    async def _userinfo(self, token: dict, subject: str) -> dict:
        """The provider's userinfo, which must be about the ID token's subject (OpenID Connect Core 5.3.2)."""
        userinfo = await self.client.userinfo(token=token)
        if userinfo.get("sub") != subject:
            raise Unauthenticated(f"the provider {self.issuer} answered userinfo of another subject")
        return dict(userinfo)

    def _wanted_name(self, claims: dict) -> str:
        for value in (claims.get(self.name_claim), str(claims.get("email") or "").partition("@")[0]):
            if isinstance(value, str) and value:
                return value
        return claims["sub"]


@contextmanager
def provider_errors(sso: SingleSignOn) -> Iterator[None]:
    """Authlib's, joserfc's and httpx2's (Authlib's HTTP client) errors of a sign-in as what they mean to the person
    signing in."""
    issuer = sso.issuer
    try:
        yield
    except MismatchingStateError:
        raise InvalidInput(
            "this sign-in is unknown here: it began in another browser, was finished already, or took longer than "
            f"{env_name('oidc_login_timeout_s')} ({sso.login_timeout_s:g} s); sign in again"
        ) from None
    except OAuthError as exc:
        raise Unauthenticated(f"the provider {issuer} refused the sign-in: {_oauth_reason(exc)}") from None
    except JoseError as exc:
        raise Unauthenticated(
            f"the ID token of the provider {issuer} was refused: {exc.error}: {shown(exc.description)}"
        ) from None
    except httpx2.HTTPStatusError as exc:
        raise Unavailable(
            f"the provider {issuer} answered {exc.response.status_code} at {shown(exc.request.url.path)}; "
            "try again later"
        ) from None
    except (httpx2.HTTPError, ValueError) as exc:  # ValueError: an answer that is not JSON
        raise Unavailable(
            f"the provider {issuer} did not answer as expected ({type(exc).__name__}); try again later"
        ) from None


def _oauth_reason(exc: OAuthError) -> str:
    return shown(f"{exc.error}: {exc.description}" if exc.description else exc.error)


def sign_in_failed(request: Request, exc: CurvefmError) -> Response:
    """A failed sign-in: a page saying why for a browser, else the JSON error body."""
    status = status_of(exc)
    log.warning("single sign-on failed (%d): %s", status, exc.message)
    if "text/html" not in request.headers.get("accept", ""):
        return error_response(exc)
    page = FAILED_PAGE.format(message=html.escape(exc.message))
    said = error_response(exc).headers  # Retry-After, WWW-Authenticate
    headers = {name: said[name] for name in ("retry-after", "www-authenticate") if name in said}
    return HTMLResponse(page, status_code=status, headers=headers)


class SignInState:
    """Starlette's session middleware, on the ``/auth/oidc`` paths only (nothing else reads or pays for it): it
    keeps a sign-in's state, nonce and PKCE verifier from the redirect to the provider until the browser comes back
    (SameSite=Lax: that return is a navigation from the provider's site), ``Secure`` over HTTPS. Its key is
    derived from the data directory's signing key. One cookie name for every port (a name per port, as the login
    cookie has, would let made-up Host ports make middlewares without end): two services of one host share it
    only while a person signs in at both at once, and then the first sign-in asks to start again."""

    def __init__(self, app, settings: Settings):
        self.app, self.settings = app, settings
        self.sessions: dict[bool, SessionMiddleware] = {}  # by whether the request came over HTTPS

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http" or not scope["path"].startswith(PATHS + "/") or not self.settings.sso:
            await self.app(scope, receive, send)
            return
        await self._session(scope)(scope, receive, send)

    def _session(self, scope) -> SessionMiddleware:
        https = Request(scope).url.scheme == "https"
        if https not in self.sessions:
            key = hmac.new(scope["app"].state.services.logins.key, b"oidc sign-in state", hashlib.sha256)
            self.sessions[https] = SessionMiddleware(
                self.app,
                secret_key=key.hexdigest(),
                session_cookie=STATE_COOKIE,
                max_age=int(self.settings.oidc_login_timeout_s),
                path=PATHS,
                same_site="lax",
                https_only=https,
            )
        return self.sessions[https]
