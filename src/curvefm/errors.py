"""The project's exceptions: one base type, and a subclass per kind of failure.

Raise the subclass that says whose fault it is; catch :class:`CurvefmError` to handle them all. Each class has
a ``code``, the short name programs see (the HTTP API's ``error`` field, a failed job's ``kind``); HTTP
statuses are chosen in :mod:`curvefm.service.errors`, not here.

* :class:`InvalidInput`: bad input a user can fix (bad mesh, unknown plugin, malformed parameters).
* :class:`NotFound`: no such shape, session, curve, job or file.
* :class:`Conflict`: the request is well formed but the state does not allow it: what it names does not fit the
  stored data (bases not computed yet, a vertex id or a path the shape does not have, a k larger than the shape
  allows). The HTTP API publishes well-formed requests in its schema; these are the ones it cannot check.
* :class:`ResourceLimit`: the input is larger than a configured limit (:class:`LimitExceeded` names the limit);
  :class:`TooMany`: more requests, sessions or concurrent jobs than a configured limit allows.
* :class:`Unauthenticated`: no credentials, or ones that are wrong, rotated or of a removed user.
* :class:`Forbidden`: the caller is known but may not do this (e.g. a route for admins only, or editing a session
  shared read-only).
* :class:`InternalError`: our failure, not the user's (an eigensolver or LAPACK failure, a non-finite result).
* :class:`Unavailable`: something the request needs (the job queue's Redis) does not answer now; try again later.
* :class:`DiskFull`: the disk of the data directory (or of the records' database) has no space left; nothing of
  the request was stored. :func:`disk_full_error` recognises it in what the filesystem and the databases raise.
"""

import errno
from typing import Any


class CurvefmError(Exception):
    """An error the project raises on purpose, with a message that says what was wrong and what to do.

    Raised as such (e.g. by a third-party plugin), it counts as invalid input.
    """

    code = "invalid"
    # set on the errors the HTTP client (curvefm.client) raises: the answer's status code and JSON body
    status: int
    body: dict[str, Any]

    def __init__(self, message: str):
        super().__init__(message)
        self.message = message


class InvalidInput(CurvefmError):
    code = "invalid"


class NotFound(CurvefmError):
    code = "not_found"


class Conflict(CurvefmError):
    code = "conflict"


class StaleRevision(Conflict):
    """A record changed (another process wrote it) since the revision an edit started from."""

    def __init__(self, kind: str, record_id: str, expected: int, stored: int):
        self.expected, self.stored = expected, stored
        super().__init__(
            f"{kind} {record_id} changed while this edit was made (revision {stored}, the edit started from "
            f"{expected}); reload it and try again"
        )


class RevisionMismatch(Conflict):
    """An edit said which revision of a record it was based on (``If-Match``), and the record is at another: the
    client shows an older state than the stored one and must reload it before editing."""

    def __init__(self, kind: str, record_id: str, expected: int, current: int):
        self.expected, self.current = expected, current
        super().__init__(
            f"{kind} {record_id} is at revision {current}, not {expected} as this edit expected: it changed "
            "since you last read it (someone else edited it); reload it and make the edit again"
        )


class Forbidden(CurvefmError):
    code = "forbidden"


class ResourceLimit(CurvefmError):
    """``setting``, when given, names what sets the limit: its environment variable."""

    code = "too_large"

    def __init__(self, message: str, setting: str | None = None):
        super().__init__(message)
        self.setting = setting


class TooMany(ResourceLimit):
    """A count or rate limit; ``retry_after`` (seconds), when given, is when trying again may succeed."""

    code = "too_many"

    def __init__(self, message: str, setting: str | None = None, retry_after: float | None = None):
        super().__init__(message, setting)
        self.retry_after = retry_after


class LimitExceeded(ResourceLimit):
    """A request asks for more than the configured limit ``name`` (e.g. ``max_waypoints``) allows.

    A limit ``max_x`` is set by the environment variable ``CURVEFM_MAX_X`` or ``curvefm serve --max-x``; the message
    names the limit, its value and how to change it.
    """

    def __init__(self, name: str, limit: int, what: str, unit: str = ""):
        self.name, self.limit = name, limit
        option = "--" + name.replace("_", "-")
        super().__init__(
            f"{what}: more than the limit of {limit}{unit} ({name}; set CURVEFM_{name.upper()} or "
            f"'curvefm serve {option}' to change it)",
            setting=f"CURVEFM_{name.upper()}",
        )


class Unauthenticated(CurvefmError):
    code = "unauthenticated"


class InternalError(CurvefmError):
    code = "internal"


class Unavailable(CurvefmError):
    code = "unavailable"


class DiskFull(CurvefmError):
    code = "disk_full"


DATA_DISK = "the data directory's disk"
DATABASE_DISK = "the records' database server's disk"
_FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT)
_SQLITE_FULL = 13  # SQLITE_FULL: "database or disk is full"
_SQLITE_FULL_INDEX = 4874  # SQLITE_IOERR_SHMSIZE: the WAL's shared-memory index could not grow (no space for it)
_POSTGRES_DISK_FULL = "53100"  # SQLSTATE disk_full


def disk_full_error(exc: BaseException) -> DiskFull | None:
    """The :class:`DiskFull` that ``exc`` means, if it (or what it was raised from, or the driver's error a
    SQLAlchemy error wraps) is a full disk: an ``OSError`` ENOSPC or EDQUOT, SQLite's SQLITE_FULL, PostgreSQL's
    SQLSTATE 53100; else None. Its message names the disk, never a path."""
    seen: set[int] = set()
    pending: list[BaseException | None] = [exc]
    while pending:
        current = pending.pop()
        if current is None or id(current) in seen:
            continue
        seen.add(id(current))
        where = _full_disk(current)
        if where is not None:
            return DiskFull(
                f"{where} is full: nothing was stored; try again once space is freed there "
                "(an operator's task: see 'A full disk' in the operations guide)"
            )
        pending += [getattr(current, "orig", None), current.__cause__, current.__context__]
    return None


def _full_disk(exc: BaseException) -> str | None:
    """Which disk ``exc`` itself says is full, if any (the drivers are recognised by their attributes: the core
    imports neither)."""
    if isinstance(exc, OSError) and exc.errno in _FULL_ERRNOS:
        return DATA_DISK
    if getattr(exc, "sqlite_errorcode", None) in (_SQLITE_FULL, _SQLITE_FULL_INDEX):
        return DATA_DISK
    if getattr(exc, "sqlstate", None) == _POSTGRES_DISK_FULL:
        return DATABASE_DISK
    return None


ERROR_KINDS: dict[str, type[CurvefmError]] = {
    cls.code: cls
    for cls in (
        InvalidInput,
        NotFound,
        Conflict,
        Forbidden,
        ResourceLimit,
        TooMany,
        Unauthenticated,
        InternalError,
        Unavailable,
        DiskFull,
    )
}
"""The class of each ``code`` (the HTTP API's ``error`` field): what :mod:`curvefm.client` raises for an answer."""

SHOWN_CHARS = 64


def shown(value: object, chars: int = SHOWN_CHARS) -> str:
    """``value`` as text for a message, cut to ``chars`` characters: an id a client sent is echoed back, and a
    megabyte of it would be echoed too."""
    text = str(value)
    return text if len(text) <= chars else text[:chars] + "..."
