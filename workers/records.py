"""Durable job records: ``<data>/jobs/<job id>.json``, one JSON file per job, beside the data jobs produce.

A record holds what the job reports (a :class:`JobInfo`) and what it takes to run it again (its arguments and
deduplication key). It is written when the job is submitted, starts, reaches a progress milestone (at most
every ``PROGRESS_WRITE_INTERVAL_S``) and ends, by whichever process sees that happen: the API, the in-process
executor, or an RQ worker (which finds the records under the job's ``data_dir`` argument). Writes are atomic
(:func:`curvefm.store.atomic_write`) and serialised by a file lock, so a record outlives what the queue
forgets: Redis restarted empty, or an API restarted in embedded mode. Such a job is then reported ``lost``.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import re
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

from curvefm.errors import InternalError
from curvefm.store import atomic_write
from curvefm.workers.interface import ENDED_STATES, JobFailure, JobInfo

PROGRESS_WRITE_INTERVAL_S = 2.0
_JOB_ID = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
_INFO_FIELDS = {f.name for f in fields(JobInfo)}


@dataclass(frozen=True)
class StoredJob:
    info: JobInfo
    kwargs: dict
    dedupe_key: str | None = None
    runner: str | None = None
    """Who runs the job: ``rq`` (any worker on the queue), or the in-process executor that took it."""


class JobRecords:
    def __init__(self, data_dir: str | os.PathLike):
        self.folder = Path(data_dir) / "jobs"
        self._progress_written: dict[str, float] = {}

    def create(self, stored: StoredJob) -> None:
        with self._locked():
            self._write(stored)

    def load(self, job_id: str) -> StoredJob | None:
        """The record, or None for an id no record has (or that cannot name one)."""
        if not _JOB_ID.match(job_id):
            return None
        try:
            return _decode(job_id, self._path(job_id).read_bytes())
        except FileNotFoundError:
            return None

    def update(self, job_id: str, **changes) -> JobInfo | None:
        """Apply ``changes`` to the job's info and return it (None when the job has no record). An ended job
        changes only to another end: a worker that outlived the Redis that knew its job may still report
        progress after the job was declared lost, and may then finish it."""
        ending = changes.get("state") in ENDED_STATES
        return self._change(job_id, lambda info: replace(info, **changes) if ending or not _ended(info) else info)

    def lose(self, job_id: str, reason: str) -> JobInfo | None:
        """Mark a job that has not ended ``lost`` with ``reason``; an ended job stays as it is."""
        lost = {"state": "lost", "message": reason, "ended_at": time.time()}
        return self._change(job_id, lambda info: info if _ended(info) else replace(info, **lost))

    def progress(self, job_id: str, fraction: float, message: str) -> None:
        """Record progress, at most every ``PROGRESS_WRITE_INTERVAL_S`` per job (each write is an fsync)."""
        now = time.monotonic()
        if now - self._progress_written.get(job_id, float("-inf")) < PROGRESS_WRITE_INTERVAL_S:
            return
        self._progress_written[job_id] = now
        self.update(job_id, progress=fraction, message=message)

    def delete(self, job_id: str) -> None:
        if _JOB_ID.match(job_id):
            self._path(job_id).unlink(missing_ok=True)

    def expire(self, ended_before: float) -> list[str]:
        """Delete the records of jobs that ended before ``ended_before`` (a ``time.time()``); return their ids."""
        expired = []
        for path in sorted(self.folder.glob("*.json")):
            with self._locked():
                stored = self.load(path.stem)
                if stored is not None and _ended(stored.info) and (stored.info.ended_at or 0) < ended_before:
                    path.unlink(missing_ok=True)
                    expired.append(path.stem)
        return expired

    def unended(self) -> list[StoredJob]:
        """Records of jobs that have not ended (queued or running, as far as their records know)."""
        stored = (self.load(path.stem) for path in self.folder.glob("*.json"))
        return [s for s in stored if s is not None and not _ended(s.info)]

    def _change(self, job_id: str, change: Callable[[JobInfo], JobInfo]) -> JobInfo | None:
        with self._locked():
            stored = self.load(job_id)
            if stored is None:
                return None
            info = change(stored.info)
            if info != stored.info:
                self._write(replace(stored, info=info))
        if _ended(info):
            self._progress_written.pop(job_id, None)
        return info

    def _write(self, stored: StoredJob) -> None:
        document = {**asdict(stored), "info": asdict(stored.info)}
        atomic_write(self._path(stored.info.id), json.dumps(document, indent=1).encode())

    def _path(self, job_id: str) -> Path:
        return self.folder / f"{job_id}.json"

    @contextlib.contextmanager
    def _locked(self) -> Iterator[None]:
        self.folder.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.folder / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            yield
        finally:
            os.close(fd)  # closing releases the lock


def records_of(job_kwargs: dict) -> JobRecords | None:
    """The records of a job's data directory (every job function takes ``data_dir``), as a worker finds them."""
    data_dir = job_kwargs.get("data_dir")
    return JobRecords(data_dir) if data_dir else None


def lost_reason(info: JobInfo, cause: str) -> str:
    doing = "running" if info.state == "started" else "queued"
    return f"{cause} while the job was {doing}; retry it (POST /jobs/{info.id}/retry) or send the same request again"


def _ended(info: JobInfo) -> bool:
    return info.state in ENDED_STATES


def _decode(job_id: str, data: bytes) -> StoredJob:
    try:
        document = json.loads(data)
        info = {key: value for key, value in document["info"].items() if key in _INFO_FIELDS}
        error = info.get("error")
        info["error"] = JobFailure(**error) if error else None
        return StoredJob(JobInfo(**info), document["kwargs"], document.get("dedupe_key"), document.get("runner"))
    except (ValueError, KeyError, TypeError) as exc:
        raise InternalError(f"the record of job {job_id} is damaged ({type(exc).__name__})") from None
