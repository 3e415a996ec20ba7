"""Job records on the ``jobs`` table (:mod:`curvefm.workers.job_rows` adapts them to the queues).

A row holds what the job reports (state, progress, message, result, failure, worker, times, owner) and what it
takes to run it again (``kwargs``, ``dedupe_key``, ``runner``). Any process that sees a job change writes it:
the API, the in-process executor, an RQ worker. An ended job changes only to another end (a worker that outlived
the Redis that knew its job may report progress after the job was declared lost, and may then finish it): the
rule is the ``WHERE`` of each update, so it holds across processes without a lock.

:class:`JobRow` has the fields of :class:`curvefm.workers.interface.JobInfo` (the core cannot import the
workers); ``error`` is ``(kind, message)`` or None and ``owner`` a user name, as ``JobInfo`` has them.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from functools import partial
from typing import Any

from sqlalchemy import Connection, Row, Select, delete, false, func, insert, or_, select, update

from curvefm.errors import Conflict, InvalidInput, NotFound, shown
from curvefm.records import models as m
from curvefm.records.common import DEFAULT_PAGE, Page, Viewer, check_page, well_formed
from curvefm.records.engine import Database
from curvefm.records.users import owner_id, owner_name
from curvefm.records.webhooks import DEFAULT_LOG_SIZE, announce_run_end

PROGRESS_WRITE_INTERVAL_S = 2.0
ENDED = m.ENDED_STATES
ACTIVE = m.ACTIVE_STATES
INFO_FIELDS = (
    "kind",
    "state",
    "progress",
    "message",
    "result",
    "worker",
    "created_at",
    "started_at",
    "ended_at",
)
"""What :meth:`Jobs.update` may change besides ``error`` (and ``result_bytes``, ``session_id``)."""


@dataclass(frozen=True)
class JobRow:
    id: str
    kind: str
    state: str
    progress: float = 0.0
    message: str = ""
    result: dict[str, Any] | None = None
    error: tuple[str, str] | None = None
    worker: str | None = None
    created_at: float | None = None
    started_at: float | None = None
    ended_at: float | None = None
    owner: str | None = None
    kwargs: dict[str, Any] = field(default_factory=dict)
    dedupe_key: str | None = None
    runner: str | None = None
    session_id: str | None = None
    result_bytes: int = 0

    @property
    def ended(self) -> bool:
        return self.state in ENDED


class Jobs:
    def __init__(self, database: Database, webhook_log_size: int = DEFAULT_LOG_SIZE):
        """``webhook_log_size``: the deliveries each webhook keeps when a job's end announces its run's end."""
        self.db, self.webhook_log_size = database, webhook_log_size
        self._progress_written: dict[str, float] = {}

    def create(
        self, job: JobRow, conn: Connection | None = None, owner: Callable[[str], int | None] | None = None
    ) -> None:
        """Store a new record (``owner`` finds the owner's user id from ``job.owner``; default: the current user
        of that name); a refinement of a session that is gone is not found."""
        if not well_formed(job.id):
            raise InvalidInput(f"a job id is 1-64 letters, digits, '-' or '_', got {job.id!r}")
        with self.db.joined(conn) as tx:
            if tx.execute(select(m.Job.id).where(m.Job.id == job.id)).first() is not None:
                raise Conflict(f"job '{job.id}' already exists")
            session = job.session_id
            if session is not None and tx.execute(select(m.Session.id).where(m.Session.id == session)).first() is None:
                raise NotFound(f"no session with id '{shown(session)}'")
            values = {f.name: getattr(job, f.name) for f in fields(job) if f.name not in ("error", "owner")}
            owner_of = owner or partial(owner_id, tx)
            tx.execute(insert(m.Job).values(**values, **_error(job.error), owner_id=owner_of(job.owner or "")))

    def load(self, job_id: str, conn: Connection | None = None) -> JobRow | None:
        """The record, or None for an id no record has (or that cannot name one)."""
        if not well_formed(job_id):
            return None
        if conn is not None:
            return _load(conn, job_id)
        with self.db.read() as fresh:
            return _load(fresh, job_id)

    def update(self, job_id: str, conn: Connection | None = None, **changes: Any) -> JobRow | None:
        """Apply ``changes`` (fields of :class:`JobRow`; ``error``: an object with ``kind`` and ``message``, a
        pair, or None) and return the record (None when there is none). An ended job changes only to another
        end."""
        return self._change(job_id, _values(changes), changes.get("state") not in ENDED, conn)

    def lose(self, job_id: str, reason: str) -> JobRow | None:
        """Mark a job that has not ended ``lost`` with ``reason``; an ended job stays as it is."""
        return self._change(job_id, {"state": "lost", "message": reason, "ended_at": time.time()}, True, None)

    def _change(
        self, job_id: str, values: dict[str, Any], only_unended: bool, conn: Connection | None
    ) -> JobRow | None:
        with self.db.joined(conn) as tx:
            query = update(m.Job).where(m.Job.id == job_id)
            unended = query.where(m.Job.state.not_in(ENDED))
            ends = values.get("state") in ENDED and tx.execute(unended.values(**values)).rowcount == 1
            if ends:  # this change ended the job (of two processes ending it at once, one did)
                announce_run_end(tx, job_id, self.webhook_log_size)
            elif values:
                tx.execute((unended if only_unended else query).values(**values))
            job = _load(tx, job_id)
        if job is not None and job.ended:
            self._progress_written.pop(job_id, None)
        return job

    def progress(self, job_id: str, fraction: float, message: str) -> None:
        """Record progress, at most every ``PROGRESS_WRITE_INTERVAL_S`` per job and process."""
        moment = time.monotonic()
        if moment - self._progress_written.get(job_id, float("-inf")) < PROGRESS_WRITE_INTERVAL_S:
            return
        self._progress_written[job_id] = moment
        with self.db.write() as conn:
            conn.execute(
                update(m.Job)
                .where(m.Job.id == job_id, m.Job.state.not_in(ENDED))
                .values(progress=fraction, message=message)
            )

    def delete(self, job_id: str) -> None:
        if well_formed(job_id):
            with self.db.write() as conn:
                conn.execute(delete(m.Job).where(m.Job.id == job_id))

    def expire(self, ended_before: float) -> list[str]:
        """Delete the records of jobs that ended before ``ended_before`` (a ``time.time()``); return their ids.
        Sessions forget them, runs keep the id as given and report the job expired, members lose the basis job."""
        with self.db.write() as conn:
            ended = (m.Job.state.in_(ENDED)) & (or_(m.Job.ended_at.is_(None), m.Job.ended_at < ended_before))
            ids = list(conn.execute(select(m.Job.id).where(ended).order_by(m.Job.id)).scalars())
            if ids:
                conn.execute(delete(m.Job).where(m.Job.id.in_(ids)))
        return ids

    def unended(self) -> list[JobRow]:
        """Records of jobs that have not ended (queued or running, as far as their records know)."""
        with self.db.read() as conn:
            rows = conn.execute(_select().where(m.Job.state.in_(ACTIVE)).order_by(m.Job.created_at)).all()
        return [_row(r) for r in rows]

    def active(self, dedupe_key: str) -> JobRow | None:
        """A queued or running job submitted with ``dedupe_key``, if any."""
        with self.db.read() as conn:
            row = conn.execute(
                _select().where(m.Job.dedupe_key == dedupe_key, m.Job.state.in_(ACTIVE)).limit(1)
            ).first()
        return None if row is None else _row(row)

    def of_session(self, session_id: str, viewer: Viewer, limit: int = DEFAULT_PAGE, offset: int = 0) -> Page[JobRow]:
        """The refinements run from the session that ``viewer`` may see (their own, others' finished ones; an
        admin all), oldest first: ``limit`` of them from ``offset``. (Whether they may read the session is the
        caller's check.)"""
        check_page(limit, offset)
        where = [m.Job.session_id == session_id]
        if not viewer.admin:
            mine = m.Job.owner_id == viewer.user_id if viewer.user_id is not None else false()
            where.append(or_(mine, m.Job.state == "finished"))
        with self.db.read() as conn:
            total = conn.execute(select(func.count()).select_from(m.Job).where(*where)).scalar() or 0
            query = _select().where(*where).order_by(m.Job.created_at, m.Job.id).offset(offset).limit(limit)
            rows = conn.execute(query).all()
        return Page([_row(r) for r in rows], total, limit, offset)

    def of_owner(self, owner: int, states: tuple[str, ...] | None = None) -> list[JobRow]:
        with self.db.read() as conn:
            query = _select().where(m.Job.owner_id == owner)
            if states:
                query = query.where(m.Job.state.in_(states))
            return [_row(r) for r in conn.execute(query.order_by(m.Job.created_at))]


def _values(changes: dict[str, Any]) -> dict[str, Any]:
    values = {}
    for name, value in changes.items():
        if name == "error":
            values.update(_error(value))
        elif name in INFO_FIELDS or name in ("result_bytes", "session_id", "kwargs", "dedupe_key", "runner"):
            values[name] = value
        elif name in ("id", "owner"):  # never change (the queues pass a whole JobInfo)
            continue
        else:
            raise InvalidInput(f"a job has no field '{name}'")
    return values


def _error(error: Any) -> dict[str, Any]:
    if error is None:
        return {"error_kind": None, "error_message": None}
    if isinstance(error, tuple | list):
        kind, message = error
    elif isinstance(error, dict):
        kind, message = error["kind"], error["message"]
    else:
        kind, message = error.kind, error.message
    return {"error_kind": kind, "error_message": message}


def _select() -> Select[Any]:
    columns = [c for c in m.Job.__table__.c if c.name != "owner_id"]
    return select(*columns, owner_name()).outerjoin(m.User, m.User.id == m.Job.owner_id)


def _load(conn: Connection, job_id: str) -> JobRow | None:
    row = conn.execute(_select().where(m.Job.id == job_id)).first()
    return None if row is None else _row(row)


def _row(row: Row[Any]) -> JobRow:
    data = row._asdict()
    kind, message = data.pop("error_kind"), data.pop("error_message")
    data["owner"] = data["owner"] or None
    return JobRow(**data, error=None if kind is None else (kind, message or ""))
