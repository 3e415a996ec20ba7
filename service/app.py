"""The FastAPI application: ``create_app(settings)`` and ``serve_main`` (what ``curvefm serve`` runs)."""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI

from curvefm.errors import ResourceLimit
from curvefm.service import routes_jobs, routes_sessions, routes_shapes
from curvefm.service.deps import start_services
from curvefm.service.errors import error_response, error_responses, install_error_handlers
from curvefm.service.hints import install_hints
from curvefm.service.settings import Settings
from curvefm.service.ui import mount_ui
from curvefm.workers.factory import check_redis

DESCRIPTION = """Interactive curve-constrained functional maps between 3D shapes.

Upload shapes, request their bases (a job), create a session on a pair, add corresponding curves (answered at
once), fetch the map or a transferred function, and request pointwise maps (a job). Vertex ids are 0-based
ids in the uploaded files. Errors are JSON: `{"error": kind, "detail": message}`; an internal error (500)
adds an `error_id` that the server log files its details under."""


class BodySizeLimit:
    """Reject requests whose declared body is larger than the upload limit before reading them (413)."""

    def __init__(self, app, limit: int):
        self.app, self.limit = app, limit

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] == "http":
            declared = dict(scope["headers"]).get(b"content-length", b"")
            if declared.isdigit() and int(declared) > self.limit:
                error = ResourceLimit(
                    f"request body of {int(declared)} bytes is larger than the limit of {self.limit} bytes "
                    "(set CURVEFM_MAX_UPLOAD_BYTES to change it)",
                )
                await error_response(error)(scope, receive, send)
                return
        await self.app(scope, receive, send)


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings.from_env()

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

    app = FastAPI(
        title="curvefm", version="0.1.0", description=DESCRIPTION, lifespan=lifespan, responses=error_responses(500)
    )
    install_error_handlers(app)
    install_hints(app)
    app.add_middleware(BodySizeLimit, limit=settings.max_upload_bytes)
    for module in (routes_shapes, routes_sessions, routes_jobs):
        app.include_router(module.router)
    mount_ui(app)  # last: its catch-all mount at / must not shadow the API routes
    return app


def serve_main(
    host: str = "127.0.0.1",
    port: int = 8000,
    data_dir: str | Path | None = None,
    redis_url: str | None = None,
    demo: bool = False,
    max_upload_bytes: int | None = None,
    log_level: str = "info",
) -> None:
    """Run the API with uvicorn until interrupted. ``None`` arguments fall back to the environment
    (``CURVEFM_DATA``, ``CURVEFM_REDIS_URL``, ``CURVEFM_MAX_UPLOAD_BYTES``); without Redis, jobs run
    in-process. One process only: sessions are cached in it and edits are serialised by in-process locks."""
    import uvicorn

    logging.basicConfig(level=log_level.upper(), format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    settings = Settings.from_env(data_dir=data_dir, redis_url=redis_url, demo=demo, max_upload_bytes=max_upload_bytes)
    if settings.redis_url:
        check_redis(settings.redis_url)  # a wrong password is one line (exit 2), not a traceback at startup
    uvicorn.run(create_app(settings), host=host, port=port, log_level=log_level)
