"""The FastAPI application: ``create_app(settings)`` and ``serve_main`` (what ``curvefm serve`` runs)."""

from __future__ import annotations

import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI
from starlette.exceptions import HTTPException

from curvefm.access import UserStore
from curvefm.errors import LimitExceeded
from curvefm.service import (
    routes_audit,
    routes_auth,
    routes_collections,
    routes_jobs,
    routes_sessions,
    routes_shapes,
)
from curvefm.service.auth import LOCAL_ADMIN, CredentialsFirst
from curvefm.service.deps import start_services
from curvefm.service.docs import DOCS_PAGES, documentation_routes
from curvefm.service.errors import error_response, error_responses, install_error_handlers
from curvefm.service.headers import SecurityHeaders, docs_csp, ui_csp
from curvefm.service.hints import install_hints
from curvefm.service.hosts import HostCheck
from curvefm.service.logs import log_config
from curvefm.service.openapi import install_openapi
from curvefm.service.ratelimit import RateLimit, make_buckets
from curvefm.service.settings import LOOPBACK_NAMES, Settings
from curvefm.service.ui import INDEX_HTML, is_ui_path, mount_ui
from curvefm.workers.factory import check_redis

DESCRIPTION = """Interactive curve-constrained functional maps between 3D shapes.

Upload shapes, request their bases (a job), create a session on a pair, add corresponding curves (answered at
once), fetch the map or a transferred function, and request pointwise maps (a job). Vertex ids are 0-based
ids in the uploaded files. Errors are JSON: `{"error": kind, "detail": message}`; an internal error (500)
adds an `error_id` that the server log files its details under.

Every route but `GET /health` needs credentials: `Authorization: Bearer TOKEN` (`curvefm users add NAME` prints a
token), or the login cookie the web page gets for one. Shapes are shared by all users; sessions, jobs and results
belong to their owner and are private unless shared."""


class BodyTooLarge(HTTPException):
    """Raised by the body-limited ``receive``: FastAPI passes an HTTP exception from reading a body through
    unchanged (any other becomes "error parsing the body"), and the error handlers answer it as an ErrorBody."""

    def __init__(self, error: LimitExceeded):
        super().__init__(status_code=413, detail=error.message)


class BodySizeLimit:
    """Bound every request body: an upload (``POST /shapes``) by ``max_upload_bytes``, any other request by
    ``max_body_bytes``.

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

        async def receive_within_limit():
            nonlocal received
            message = await receive()
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
        try:
            yield
        finally:
            services.close()
            await buckets.close()

    app = FastAPI(
        title="curvefm",
        version="0.1.0",
        description=DESCRIPTION,
        lifespan=lifespan,
        responses=error_responses(500),
        openapi_url=None,  # served by documentation_routes(), behind credentials like the rest of the API
        docs_url=None,
        redoc_url=None,
    )
    install_error_handlers(app)
    install_openapi(app)
    install_hints(app)
    # the last added runs first: headers on every answer, then the Host check, the rate limit, credentials
    # (of writes), the body size
    app.add_middleware(BodySizeLimit, settings=settings)
    app.add_middleware(CredentialsFirst)  # before the body is read, after the rate limit
    if settings.rate_limit:
        app.add_middleware(RateLimit, settings=settings, buckets=buckets, exempt=is_unlimited)
    app.add_middleware(HostCheck, allowed=settings.allowed_hosts)
    app.add_middleware(SecurityHeaders, csp=ui_csp(INDEX_HTML), docs_csp=docs_csp(DOCS_PAGES.values()))
    for module in (routes_auth, routes_shapes, routes_sessions, routes_collections, routes_jobs, routes_audit):
        app.include_router(module.router)
    app.include_router(routes_jobs.public)
    app.include_router(documentation_routes())
    mount_ui(app)  # last: its catch-all mount at / must not shadow the API routes
    return app


def is_unlimited(path: str) -> bool:
    """``/health`` and the UI's static files are not rate limited."""
    return path == "/health" or is_ui_path(path)


def login_instructions(users: UserStore, host: str, port: int) -> str:
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


def serve_main(host: str = LOOPBACK_NAMES[1], port: int = 8000, log_level: str = "info", **overrides) -> None:
    """Run the API with uvicorn until interrupted. ``overrides`` set :class:`Settings` by name (``data_dir``,
    ``redis_url``, ``demo``, the limits); ``None`` ones fall back to the environment (``CURVEFM_DATA``,
    ``CURVEFM_REDIS_URL``, ``CURVEFM_MAX_UPLOAD_BYTES``, ...); ``host`` chooses the default allowed hosts.
    Without Redis, jobs run in-process. Several processes may serve one data directory: edits of a session are
    serialised by a lock file per session."""
    import uvicorn

    settings = Settings.from_env(bind_host=host, **overrides)
    if settings.redis_url:
        check_redis(settings.redis_url)  # a wrong password is one line (exit 2), not a traceback at startup
    print(login_instructions(UserStore(settings.data_dir), host, port), flush=True)
    app = create_app(settings)
    sys.setswitchinterval(settings.gil_switch_ms / 1000)
    uvicorn.run(
        app,
        host=host,
        port=port,
        log_level=log_level,
        log_config=log_config(log_level),
        timeout_keep_alive=settings.keep_alive_s,
        http="h11",  # httptools answers malformed requests with plain text, not with a JSON error body
    )
