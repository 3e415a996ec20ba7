"""Durable job records, in the records' database (:mod:`curvefm.records.jobs`, the ``jobs`` table).

A record holds what the job reports (a :class:`JobInfo`) and what it takes to run it again (its arguments and
deduplication key). It is written when the job is submitted, starts, reaches a progress milestone (at most every
``PROGRESS_WRITE_INTERVAL_S``) and ends, by whichever process sees that happen: the API, the in-process executor,
or an RQ worker (which opens the database of the job's ``data_dir`` argument, or ``CURVEFM_DATABASE_URL``). A
record outlives what the queue forgets: Redis restarted empty, or an API restarted in embedded mode. Such a job is
then reported ``lost``. A finished job's record carries the size of its result files (``result_bytes``), which
count in its owner's byte quota until the job expires.

This module converts between the queue's :class:`JobInfo` and the database's rows (the core cannot import
``JobInfo``).
"""

from __future__ import annotations

import logging
import os
from contextlib import AbstractContextManager
from dataclasses import asdict, fields
from pathlib import Path

from sqlalchemy import Connection
from sqlalchemy.exc import SQLAlchemyError

from curvefm.records.common import Page, Viewer
from curvefm.records.engine import Database, shared_database
from curvefm.records.jobs import JobRow, Jobs
from curvefm.records.webhooks import DEFAULT_LOG_SIZE
from curvefm.workers.interface import Admission, JobFailure, JobInfo, StoredJob

_INFO = [f.name for f in fields(JobInfo)]
RECORD_ERRORS = (OSError, SQLAlchemyError)
"""What writing a job's record raises when the disk is full or the database does not answer."""
log = logging.getLogger("curvefm.workers")


class DbJobRecords:
    """The job records of a data directory (its database: ``database``, else the directory's, see
    :func:`curvefm.records.database_url`); a job's end that ends a run keeps each webhook's newest
    ``webhook_log_size`` deliveries."""

    def __init__(
        self,
        data_dir: str | os.PathLike | None = None,
        database: Database | None = None,
        webhook_log_size: int = DEFAULT_LOG_SIZE,
    ):
        self.db = database or shared_database(data_dir)
        self.rows = Jobs(self.db, webhook_log_size)
        self.results = Path(data_dir) / "results" if data_dir is not None else None

    def create(self, stored: StoredJob, conn: Connection | None = None) -> None:
        """Store a new job's record (in ``conn``'s transaction when given: the one that admitted the job)."""
        info = asdict(stored.info)
        error = stored.info.error
        info["error"] = None if error is None else (error.kind, error.message)
        info.update(kwargs=stored.kwargs, dedupe_key=stored.dedupe_key, runner=stored.runner)
        self.rows.create(JobRow(**info, session_id=stored.session_id), conn)

    def admitted(self, admit: Admission | None) -> AbstractContextManager[Connection]:
        """The transaction that admits a job and writes its record: ``admit``'s (a quota check), else a plain
        write."""
        return (admit or self.db.write)()

    def load(self, job_id: str) -> StoredJob | None:
        row = self.rows.load(job_id)
        return None if row is None else stored_of(row)

    def update(self, job_id: str, **changes) -> JobInfo | None:
        """Apply ``changes`` to the job's info and return it (None when the job has no record). An ended job
        changes only to another end. A job finishing is charged the size of its result files."""
        if changes.get("state") == "finished" and self.results is not None:
            changes["result_bytes"] = folder_bytes(self.results / job_id)
        row = self.rows.update(job_id, **changes)
        return None if row is None else info_of(row)

    def lose(self, job_id: str, reason: str) -> JobInfo | None:
        """Mark a job that has not ended ``lost`` with ``reason``; an ended job stays as it is."""
        row = self.rows.lose(job_id, reason)
        return None if row is None else info_of(row)

    def progress(self, job_id: str, fraction: float, message: str) -> None:
        self.rows.progress(job_id, fraction, message)

    def delete(self, job_id: str) -> None:
        self.rows.delete(job_id)

    def expire(self, ended_before: float) -> list[str]:
        """Delete the records of jobs that ended before ``ended_before`` (a ``time.time()``); return their ids."""
        return self.rows.expire(ended_before)

    def unended(self) -> list[StoredJob]:
        """Records of jobs that have not ended (queued or running, as far as their records know)."""
        return [stored_of(row) for row in self.rows.unended()]

    def of_session(self, session_id: str, viewer: Viewer, limit: int, offset: int) -> Page[JobInfo]:
        """The refinements of the session that ``viewer`` may see, oldest first (see
        :meth:`curvefm.records.jobs.Jobs.of_session`)."""
        page = self.rows.of_session(session_id, viewer, limit, offset)
        return Page([info_of(row) for row in page.items], page.total, page.limit, page.offset)

    def active_stored(self, dedupe_key: str) -> StoredJob | None:
        """The record of a queued or running job submitted with ``dedupe_key`` (by any process), if any."""
        row = self.rows.active(dedupe_key)
        return None if row is None else stored_of(row)


def stored_of(row: JobRow) -> StoredJob:
    return StoredJob(info_of(row), row.kwargs, row.dedupe_key, row.runner, row.session_id)


def info_of(row: JobRow) -> JobInfo:
    values = {name: getattr(row, name) for name in _INFO}
    values["error"] = None if row.error is None else JobFailure(*row.error)
    return JobInfo(**values)


def folder_bytes(folder: Path) -> int:
    """The bytes of the files under ``folder`` (0 when there is none)."""
    if not folder.is_dir():
        return 0
    return sum(path.stat().st_size for path in folder.rglob("*") if path.is_file())


def records_of(job_kwargs: dict, webhook_log_size: int = DEFAULT_LOG_SIZE) -> DbJobRecords | None:
    """The records of a job's data directory (every job function takes ``data_dir``), as a worker finds them."""
    data_dir = job_kwargs.get("data_dir")
    return DbJobRecords(data_dir, webhook_log_size=webhook_log_size) if data_dir else None


def note_unrecorded(job_id: str, state: str, exc: Exception) -> None:
    """Say in the log that a job's record lags behind its state (``exc``: one of :data:`RECORD_ERRORS`)."""
    log.warning("job %s %s; its record is not written yet (%s)", job_id, state, JobFailure.of(exc).message)


def lost_reason(info: JobInfo, cause: str) -> str:
    doing = "running" if info.state == "started" else "queued"
    return f"{cause} while the job was {doing}; retry it (POST /jobs/{info.id}/retry) or send the same request again"
