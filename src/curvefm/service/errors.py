"""Errors as HTTP answers: the one place where error classes become statuses, and their JSON bodies.

A body is ``{"error": code, "detail": message, ...}`` (:class:`curvefm.service.models.ErrorBody`). An internal
error answers 500 with an ``error_id`` and one readable line; its traceback goes to the server log under that id.
Something the request needs that does not answer now (the job queue's Redis) is a 503 with ``Retry-After``. A full
disk (:func:`curvefm.errors.disk_full_error`: the filesystem's or a database's error) is a 507 naming the disk.
"""

from __future__ import annotations

import logging
import math
import uuid
from typing import Any, Literal, overload

from fastapi import FastAPI, Request, Response
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from redis.exceptions import ConnectionError as RedisConnectionError
from redis.exceptions import TimeoutError as RedisTimeoutError
from sqlalchemy.exc import OperationalError
from starlette.exceptions import HTTPException
from starlette.requests import ClientDisconnect

from curvefm import registry
from curvefm.errors import (
    Conflict,
    CurvefmError,
    DiskFull,
    Forbidden,
    InternalError,
    InvalidInput,
    LimitExceeded,
    NotFound,
    ResourceLimit,
    RevisionMismatch,
    TooMany,
    Unauthenticated,
    Unavailable,
    disk_full_error,
    shown,
)
from curvefm.registry import BasisPlugin, ConverterPlugin, MethodPlugin, Plugin, TracerPlugin
from curvefm.service.headers import API_CSP, FIXED_HEADERS
from curvefm.service.models import ErrorBody
from curvefm.service.ui import api_methods

log = logging.getLogger("curvefm.service")

STATUS: dict[type[CurvefmError], int] = {
    CurvefmError: 400,  # raised as such (e.g. by a third-party plugin): a user error
    InvalidInput: 400,
    Unauthenticated: 401,
    Forbidden: 403,
    NotFound: 404,
    Conflict: 409,
    ResourceLimit: 413,
    TooMany: 429,
    InternalError: 500,
    Unavailable: 503,
    DiskFull: 507,
}
CODE = {status: cls.code for cls, status in STATUS.items()}
"""The ``error`` code of a status (for the framework's own errors: unknown paths, methods not allowed)."""
RETRY_AFTER_S = 5
"""What a 503 asks a client to wait before trying again."""


class BoundExceeded(RequestValidationError):
    """A body past a bound of the published schema that is a configured limit: the schema's 422, whose ``limit``
    names the setting."""

    def __init__(self, path: list, error: LimitExceeded):
        super().__init__([{"loc": ("body", *path), "msg": error.message, "type": "limit"}])
        self.setting = error.setting


class UnknownPlugin(InvalidInput):
    def __init__(self, kind: str, name: str):
        self.available = registry.names(kind)
        super().__init__(f"unknown {kind} '{shown(name)}'; installed {kind}s: {', '.join(self.available) or 'none'}")


@overload
def require_plugin(kind: Literal["tracer"], name: str) -> TracerPlugin[Any]: ...
@overload
def require_plugin(kind: Literal["basis"], name: str) -> BasisPlugin[Any]: ...
@overload
def require_plugin(kind: Literal["converter"], name: str) -> ConverterPlugin[Any]: ...
@overload
def require_plugin(kind: Literal["method"], name: str) -> MethodPlugin[Any]: ...
@overload
def require_plugin(kind: str, name: str) -> Plugin[Any]: ...
def require_plugin(kind: str, name: str) -> Plugin[Any]:
    """The plugin, or an error listing the installed ones. (``registry.get`` caches what it loaded; listing
    entry points costs tens of milliseconds, so it is done only when the name is unknown.)"""
    try:
        return registry.get(kind, name)
    except CurvefmError:
        if name in registry.names(kind):
            raise
        raise UnknownPlugin(kind, name) from None


def status_of(exc: CurvefmError) -> int:
    return next(STATUS[cls] for cls in type(exc).__mro__ if cls in STATUS)


DESCRIPTIONS = {
    400: "input the schema cannot describe is wrong, e.g. parameters a plugin refuses (the detail names it), or a "
    "Host header that names no host this server answers (CURVEFM_ALLOWED_HOSTS)",
    401: "no valid token: a bearer token, or the login cookie",
    403: "the caller is known but may not do this (an admin's route, a write from a foreign Origin)",
    404: "no such shape, session, curve, job or result file",
    408: "the request body stopped arriving for longer than CURVEFM_BODY_TIMEOUT",
    409: "well formed, but the stored data does not allow it: a vertex id or path the shape does not have, a k "
    "larger than the shape allows, bases not computed yet, a job that already ended, an edit whose If-Match "
    "revision is no longer the session's (its body's revision is the current one)",
    413: "larger than a configured limit (the detail names the limit and its setting): the body's size "
    "(CURVEFM_MAX_BODY_BYTES, uploads CURVEFM_MAX_UPLOAD_BYTES), its nesting (CURVEFM_MAX_JSON_DEPTH), or a limit "
    "that depends on what is stored (the schema's own bounds answer 422)",
    422: "the request does not match this schema (fields names each problem); past a bound that is a configured "
    "limit (x-curvefm-limit), limit names its setting",
    429: "more requests (CURVEFM_RATE_LIMIT), sessions or concurrent jobs than a configured limit allows; "
    "Retry-After when it passes",
    500: "the server's failure, not the request's (error_id files the details in the server log)",
    503: "a service the request needs is down (Redis, the records' database), or the session stayed busy with "
    "another request longer than CURVEFM_SESSION_LOCK_TIMEOUT; Retry-After says when to try again",
    507: "the disk of the data directory (or of the records' database) is full: nothing of the request was stored; "
    "try again once an operator has freed space",
}


def error_responses(*statuses: int, described: dict[int, str] | None = None) -> dict[int | str, dict]:
    """OpenAPI ``responses`` for these error statuses, with what each means here (``described`` overrides);
    the app declares 500, which any route can answer."""
    descriptions = {**DESCRIPTIONS, **(described or {})}
    return {status: {"model": ErrorBody, "description": descriptions[status]} for status in statuses}


def error_response(exc: CurvefmError, detail: str | None = None) -> JSONResponse:
    """The JSON answer to a user's error (4xx) or to an unavailable dependency (503), its message or
    ``detail``; internal errors go through :func:`internal_error_response`."""
    body: dict[str, Any] = {"error": exc.code, "detail": detail or exc.message}
    headers = {}
    if isinstance(exc, UnknownPlugin):
        body["available"] = exc.available
    if isinstance(exc, RevisionMismatch):
        body["revision"] = exc.current
    if isinstance(exc, ResourceLimit) and exc.setting:
        body["limit"] = exc.setting
    if isinstance(exc, Unavailable):
        headers["Retry-After"] = str(RETRY_AFTER_S)
    if isinstance(exc, TooMany) and exc.retry_after is not None:
        headers["Retry-After"] = str(max(1, math.ceil(exc.retry_after)))
    if isinstance(exc, Unauthenticated):
        headers["WWW-Authenticate"] = "Bearer"
    return JSONResponse(body, status_code=status_of(exc), headers=headers)


def project_error_response(request: Request, exc: CurvefmError) -> JSONResponse:
    """The answer to any of the project's errors: 500 with an error id for an internal one, 507 (logged for the
    operator) for a full disk, else :func:`error_response`."""
    if isinstance(exc, InternalError):
        return internal_error_response(request, exc)
    if isinstance(exc, DiskFull):
        return disk_full_response(request, exc)
    return error_response(exc)


OUTAGES = (OperationalError, RedisConnectionError, RedisTimeoutError)
"""What the records' database or Redis raise when they do not answer (gone, restarting, a name that does not
resolve, a SQLite file held by another writer past its busy timeout)."""


def outage(exc: Exception) -> DiskFull | Unavailable:
    """The project's error for one of :data:`OUTAGES`: 507 for a database whose disk is full, else 503."""
    if not isinstance(exc, OperationalError):
        return Unavailable("the job queue (Redis) does not answer; try again")
    reason = " ".join(str(exc.orig).split())[:200]
    return disk_full_error(exc) or Unavailable(f"the records' database did not answer ({reason}); try again")


class Outages:
    """ASGI middleware around those that use the records' database or Redis (the credentials' check reads the users,
    the rate limit counts in Redis): a dependency that does not answer while they run is the 503 (or 507) a route's
    failure gets from the exception handlers, not a 500. Nothing is answered twice: an answer already started is
    left to the server."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = False

        async def send_and_note(message) -> None:
            nonlocal started
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, receive, send_and_note)
        except OUTAGES as exc:
            if started:
                raise
            log.warning("%s %s: %s", scope["method"], scope["path"], " ".join(str(exc).split())[:300])
            await project_error_response(Request(scope), outage(exc))(scope, receive, send)


def internal_error_response(request: Request, exc: Exception) -> JSONResponse:
    """500 with an error id; the traceback is logged under that id, never sent."""
    error_id = uuid.uuid4().hex[:12]
    log.error("internal error %s on %s %s", error_id, request.method, request.url.path, exc_info=exc)
    line = exc.message if isinstance(exc, InternalError) else "the server failed to handle this request"
    detail = f"{line} (error id {error_id}; the server log has the details)"
    body = {"error": InternalError.code, "detail": detail, "error_id": error_id}
    # answered by Starlette's outermost middleware, so the security headers middleware never sees it
    headers = {**FIXED_HEADERS, "content-security-policy": API_CSP}
    return JSONResponse(body, status_code=500, headers=headers)


def disk_full_response(request: Request, exc: DiskFull) -> JSONResponse:
    """507, logged as a warning for the operator (without a traceback: the cause is known)."""
    log.warning("%s %s: %s", request.method, request.url.path, exc.message)
    return error_response(exc)


def allow_header(request: Request, default: str) -> str:
    """Every method the API serves at the request's path (the router names only the first route's methods,
    and ``GET /jobs/{id}`` and ``DELETE /jobs/{id}`` are two routes); ``default`` where no API route matches."""
    return ", ".join(api_methods(request.app.router.routes, request.scope)) or default


def install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(CurvefmError)
    async def curvefm_error(request: Request, exc: CurvefmError) -> JSONResponse:
        return project_error_response(request, exc)

    @app.exception_handler(OperationalError)
    async def database_error(request: Request, exc: OperationalError) -> JSONResponse:
        return project_error_response(request, outage(exc))

    @app.exception_handler(ClientDisconnect)
    async def client_gone(request: Request, exc: ClientDisconnect) -> Response:
        log.info("%s %s: the client went away before its request body arrived", request.method, request.url.path)
        return Response(status_code=400)  # nobody is left to read it

    @app.exception_handler(OSError)
    async def file_error(request: Request, exc: OSError) -> JSONResponse:
        full = disk_full_error(exc)
        return internal_error_response(request, exc) if full is None else disk_full_response(request, full)

    @app.exception_handler(Exception)
    async def unexpected_error(request: Request, exc: Exception) -> JSONResponse:
        full = disk_full_error(exc)  # raised from a full disk's error by code that wrapped it
        return internal_error_response(request, exc) if full is None else disk_full_response(request, full)

    @app.exception_handler(HTTPException)
    async def http_error(request: Request, exc: HTTPException) -> JSONResponse:
        body = {"error": CODE.get(exc.status_code, InvalidInput.code), "detail": str(exc.detail)}
        headers = dict(exc.headers or {})
        if exc.status_code == 405:
            headers["Allow"] = allow_header(request, headers.get("Allow", ""))
        return JSONResponse(body, status_code=exc.status_code, headers=headers)

    @app.exception_handler(RequestValidationError)
    async def validation_error(request: Request, exc: RequestValidationError) -> JSONResponse:
        fields = [{"field": ".".join(str(part) for part in e["loc"]), "problem": e["msg"]} for e in exc.errors()]
        detail = "; ".join(f"{f['field']}: {f['problem']}" for f in fields)
        body: dict[str, Any] = {"error": InvalidInput.code, "detail": detail, "fields": fields}
        if isinstance(exc, BoundExceeded):
            body["limit"] = exc.setting
        return JSONResponse(body, status_code=422)
