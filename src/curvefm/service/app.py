"""The FastAPI application: ``create_app(settings)`` and ``serve_main`` (what ``curvefm serve`` runs)."""

from __future__ import annotations

import os
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from types import FrameType

import uvicorn
from fastapi import FastAPI
from starlette.exceptions import HTTPException

from curvefm.access import Users
from curvefm.errors import LimitExceeded
from curvefm.service import (
    routes_audit,
    routes_auth,
    routes_checks,
    routes_collections,
    routes_comments,
    routes_events,
    routes_jobs,
    routes_reviews,
    routes_sessions,
    routes_shapes,
    routes_webhooks,
)
from curvefm.service.auth import LOCAL_ADMIN, CredentialsFirst
from curvefm.service.connections import timed_h11, timed_receive
from curvefm.service.deps import open_records, start_services
from curvefm.service.docs import DOCS_PAGES, documentation_routes, install_docs_login
from curvefm.service.errors import Outages, error_response, error_responses, install_error_handlers
from curvefm.service.headers import SecurityHeaders, docs_csp, ui_csp
from curvefm.service.hints import install_hints
from curvefm.service.hosts import HostCheck
from curvefm.service.logs import log_config
from curvefm.service.oidc import SignInState
from curvefm.service.openapi import install_openapi
from curvefm.service.ratelimit import RateLimit, make_buckets
from curvefm.service.session_events import SessionEvents
from curvefm.service.settings import LOOPBACK_NAMES, Settings
from curvefm.service.ui import INDEX_HTML, is_ui_path, mount_ui
from curvefm.workers.factory import check_redis

DESCRIPTION = """Interactive curve-constrained functional maps between 3D shapes.

Upload shapes, request their bases (a job), create a session on a pair, add corresponding curves (answered at
once), fetch the map or a transferred function, and request pointwise maps (a job). Vertex ids are 0-based
ids in the uploaded files. Errors are JSON: `{"error": kind, "detail": message}`; an internal error (500)
adds an `error_id` that the server log files its details under.

Every route but `GET /health` and the sign-in's own (`/auth/methods`, `/auth/oidc/*`) needs credentials:
`Authorization: Bearer TOKEN` (`curvefm users add NAME` prints a token; `POST /auth/token` makes one for the caller),
or the login cookie the web page gets for one, or for a single sign-on at the lab's OpenID Connect provider.
Shapes are shared by all users; sessions, jobs and results belong to their owner and are private unless shared."""


class BodyTooLarge(HTTPException):
    """Raised by the body-limited ``receive``: FastAPI passes an HTTP exception from reading a body through
    unchanged (any other becomes "error parsing the body"), and the error handlers answer it as an ErrorBody."""

    def __init__(self, error: LimitExceeded):
        super().__init__(status_code=413, detail=error.message)


class BodySizeLimit:
    """Bound every request body: an upload (``POST /shapes``) by ``max_upload_bytes``, any other request by
    ``max_body_bytes``, and each read of it by ``body_timeout_s``.

    A declared Content-Length over the limit is answered 413 at once, before anything is read. Otherwise the body
    is counted as it arrives, whatever Content-Length says and for chunked bodies alike, and the read that would
    pass the limit raises :class:`BodyTooLarge` instead of handing the bytes on: no more than the limit is ever
    parsed or spooled to a temporary file.
    """

    def __init__(self, app, settings: Settings):
        self.app, self.settings = app, settings

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        name = "max_upload_bytes" if (scope["method"], scope["path"]) == ("POST", "/shapes") else "max_body_bytes"
        limit = getattr(self.settings, name)
        declared = dict(scope["headers"]).get(b"content-length", b"")
        if declared.isdigit() and int(declared) > limit:
            error = LimitExceeded(name, limit, f"a request body of {int(declared)} bytes", " bytes")
            await error_response(error)(scope, receive, send)
            return
        received = 0

        timed = timed_receive(receive, self.settings.body_timeout_s)

        async def receive_within_limit():
            nonlocal received
            message = await timed()
            received += len(message.get("body", b""))
            if received > limit:
                raise BodyTooLarge(LimitExceeded(name, limit, "the request body", " bytes"))
            return message

        await self.app(scope, receive_within_limit, send)


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings.from_env()
    buckets = make_buckets(settings)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        services = start_services(settings)
        app.state.services = services
        if settings.demo:
            from curvefm.service.demo import start_demo

            services.stop_events.append(start_demo(services))
        events = app.state.events = SessionEvents(services)
        services.live.notify = events.notify
        await events.start()
        try:
            yield
        finally:
            await events.close()
            services.close()
            await buckets.close()

    app = FastAPI(
        title="curvefm",
        version="0.1.0",
        description=DESCRIPTION,
        lifespan=lifespan,
        responses=error_responses(400, 500, 503),
        openapi_url=None,  # served by documentation_routes(), behind credentials like the rest of the API
        docs_url=None,
        redoc_url=None,
    )
    install_error_handlers(app)
    install_openapi(app, settings, rate_limited=lambda path: not is_unlimited(path))
    install_hints(app)
    install_docs_login(app)
    # the last added runs first: headers on every answer, then the Host check, 503 for a database or Redis that does
    # not answer while the next ones use them, the rate limit, credentials (of writes), the body size, the single
    # sign-on's state cookie
    app.add_middleware(SignInState, settings=settings)
    app.add_middleware(BodySizeLimit, settings=settings)
    app.add_middleware(CredentialsFirst)  # before the body is read, after the rate limit
    if settings.rate_limit:
        app.add_middleware(RateLimit, settings=settings, buckets=buckets, exempt=is_unlimited)
    app.add_middleware(Outages)
    app.add_middleware(HostCheck, allowed=settings.allowed_hosts)
    app.add_middleware(SecurityHeaders, csp=ui_csp(INDEX_HTML), docs_csp=docs_csp(DOCS_PAGES.values()))
    routes = (
        routes_auth,
        routes_shapes,
        routes_sessions,
        routes_events,
        routes_collections,
        routes_webhooks,
        routes_reviews,
        routes_comments,
        routes_checks,
        routes_jobs,
        routes_audit,
    )
    for module in routes:
        app.include_router(module.router)
    app.include_router(routes_jobs.public)
    app.include_router(documentation_routes())
    mount_ui(app)  # last: its catch-all mount at / must not shadow the API routes
    return app


def is_unlimited(path: str) -> bool:
    """``/health`` and the UI's static files are not rate limited."""
    return path == "/health" or is_ui_path(path)


def login_instructions(users: Users, host: str, port: int) -> str:
    """What ``curvefm serve`` prints: the login URL of a local admin it creates when there is no user, else how
    to log in (tokens are stored hashed, so an existing one cannot be shown again)."""
    shown_host = "127.0.0.1" if host in ("", "0.0.0.0", "::") else f"[{host}]" if ":" in host else host
    url = f"http://{shown_host}:{port}/?token="
    token = users.ensure_local_admin(LOCAL_ADMIN)
    if token is not None:
        return f"curvefm: created the admin user '{LOCAL_ADMIN}'. Open this URL to log in:\n\n    {url}{token}\n"
    return (
        f"curvefm: log in by opening {url}YOUR_TOKEN (an admin makes a token with 'curvefm users add NAME', "
        "or a new one with 'curvefm users token NAME --rotate')"
    )


FORWARDED_VARIABLE = "FORWARDED_ALLOW_IPS"
"""uvicorn's: the addresses whose X-Forwarded-For/-Proto are believed (unset: none)."""


def serve_main(host: str = LOOPBACK_NAMES[1], port: int = 8000, log_level: str = "info", **overrides) -> None:
    """Run the API with uvicorn until interrupted. ``overrides`` set :class:`Settings` by name (``data_dir``,
    ``redis_url``, ``demo``, the limits); ``None`` ones fall back to the environment (``CURVEFM_DATA``,
    ``CURVEFM_REDIS_URL``, ``CURVEFM_MAX_UPLOAD_BYTES``, ...); ``host`` chooses the default allowed hosts.
    Without Redis, jobs run in-process. Several processes may serve one database: an edit's write checks the
    session's revision in its transaction."""
    settings = Settings.from_env(bind_host=host, **overrides)
    if settings.redis_url:
        check_redis(settings.redis_url)  # a wrong password is one line (exit 2), not a traceback at startup
    database, imported = open_records(settings)  # a database that is not curvefm's stops the start here
    if imported is not None:
        lines = "\n".join(f"  {line}" for line in imported.lines())
        print(f"curvefm: imported the records of {settings.data_dir} into {database.shown}:\n{lines}", flush=True)
    print(login_instructions(Users(database), host, port), flush=True)
    app = create_app(settings)
    sys.setswitchinterval(settings.gil_switch_ms / 1000)
    config = uvicorn.Config(
        app,
        host=host,
        port=port,
        log_level=log_level,
        log_config=log_config(log_level),
        timeout_keep_alive=settings.keep_alive_s,  # type: ignore[arg-type]  # typed int; asyncio takes a float delay
        http=timed_h11(settings.header_timeout_s),  # h11: httptools answers malformed requests with plain text
        # X-Forwarded-* only from the proxies an operator names (uvicorn trusts 127.0.0.1, so anything on the host)
        proxy_headers=FORWARDED_VARIABLE in os.environ,
        forwarded_allow_ips=os.environ.get(FORWARDED_VARIABLE),
    )
    StreamEndingServer(config, app).run()


class StreamEndingServer(uvicorn.Server):
    """uvicorn's server that ends the open event streams when told to stop: it waits for every open response
    before it shuts down, and a stream would never end by itself."""

    def __init__(self, config: uvicorn.Config, app: FastAPI):
        super().__init__(config)
        self.app = app

    def handle_exit(self, sig: int, frame: FrameType | None) -> None:
        super().handle_exit(sig, frame)
        events = getattr(self.app.state, "events", None)
        if events is not None:
            events.stop()
