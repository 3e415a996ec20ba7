"""Jobs on RQ (Redis Queue): enqueueing, status, cancelling, and why a job failed.

Queue names are ``<prefix>curvefm-basis`` and ``<prefix>curvefm-refine`` (``CURVEFM_QUEUE_PREFIX``, empty by
default, lets several deployments or test runs share one Redis). Everything crosses Redis as JSON
(:data:`curvefm.workers.connection.SERIALIZER`): workers must use it too, as ``curvefm worker`` does. Every job
carries callbacks that keep its durable record (:mod:`curvefm.workers.records`) and, on failure, store its kind
and message as data in ``job.meta["failure"]``, never read back from traceback text. Jobs whose worker died
are handled by :mod:`curvefm.workers.reaper`. While Redis does not answer, every operation raises
:class:`~curvefm.errors.Unavailable`.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import re
import threading
import time
import uuid
from dataclasses import asdict, fields, replace
from datetime import UTC, datetime
from pathlib import Path

from redis import Redis
from rq import Callback, Queue, Retry
from rq.command import send_stop_job_command
from rq.exceptions import AbandonedJobError, InvalidJobOperation, NoSuchJobError
from rq.job import Job, JobStatus

from curvefm.errors import NotFound, Unavailable
from curvefm.workers.connection import SERIALIZER, UNREACHABLE, connect
from curvefm.workers.interface import (
    ENDED_STATES,
    JOB_KINDS,
    KEEP_ENDED_S,
    WORKER_LOST,
    JobFailure,
    JobInfo,
    JobQueue,
    cancel_needed,
    check_kind,
    one_line,
    unknown_job,
)
from curvefm.workers.jobs import JOB_FUNCTIONS
from curvefm.workers.reaper import reap_abandoned, start_reaper
from curvefm.workers.records import JobRecords, StoredJob, lost_reason, records_of

log = logging.getLogger("curvefm.workers")

JOB_TIMEOUT_S = 3 * 3600
RECORDED_STATES_KEPT = 10_000
QUEUE_LOST = "the job queue (Redis) no longer knows this job (it restarted without its data, or was emptied)"
REDIS_DOWN = (
    "the job queue (Redis) does not answer, so jobs can be neither submitted nor followed until it is back; "
    "curve edits, maps and transfers still work"
)

_STATES = {
    JobStatus.CREATED: "queued",
    JobStatus.QUEUED: "queued",
    JobStatus.DEFERRED: "queued",
    JobStatus.SCHEDULED: "queued",
    JobStatus.STARTED: "started",
    JobStatus.FINISHED: "finished",
    JobStatus.FAILED: "failed",
    JobStatus.STOPPED: "canceled",
    JobStatus.CANCELED: "canceled",
}
_JOB_ID = re.compile(r"^[A-Za-z0-9_-]{1,64}$")


def queue_names(prefix: str = "") -> dict[str, str]:
    """RQ queue name per job kind."""
    return {kind: f"{prefix}curvefm-{kind}" for kind in JOB_KINDS}


def _needs_redis(method):
    """Turn Redis not answering into :class:`~curvefm.errors.Unavailable` (logged without the URL)."""

    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        try:
            return method(*args, **kwargs)
        except UNREACHABLE as exc:
            log.warning("Redis does not answer: %s", one_line(str(exc)))
            raise Unavailable(REDIS_DOWN) from None

    return wrapper


class RQQueue(JobQueue):
    """Jobs on RQ; their records go under ``data_dir``, which the workers share."""

    mode = "redis"

    def __init__(
        self,
        redis_url: str,
        data_dir: str | Path,
        prefix: str = "",
        retries: int = 1,
        keep_ended_s: float = KEEP_ENDED_S,
    ):
        self.connection = connect(redis_url)
        self.records = JobRecords(data_dir)
        self.retries = retries
        self.keep_ended_s = max(1, round(keep_ended_s))  # RQ's TTLs are whole seconds
        self.queues = {
            kind: Queue(name, connection=self.connection, serializer=SERIALIZER)
            for kind, name in queue_names(prefix).items()
        }
        self._dedupe_prefix = f"curvefm:{prefix}dedupe:"
        self._stop_reaper: threading.Event | None = None
        self._recorded_states: dict[str, str] = {}

    def start_reaper(self, interval_s: float) -> None:
        """Hand jobs of dead workers to RQ's retry-or-fail handling every ``interval_s``, until :meth:`close`."""
        self._stop_reaper = start_reaper(self.connection, list(self.queues.values()), interval_s)

    @_needs_redis
    def submit(self, kind: str, kwargs: dict, dedupe_key: str | None = None, owner: str | None = None) -> JobInfo:
        check_kind(kind)
        if dedupe_key is None:
            return self._enqueue(kind, kwargs, None, owner)
        key = self._dedupe_prefix + dedupe_key
        with self.connection.lock(key + ":lock", timeout=30, blocking_timeout=30):
            existing = self.connection.get(key)
            if existing is not None:
                info = self._find(existing.decode())
                if info is not None and info.state not in ENDED_STATES:
                    return info
            info = self._enqueue(kind, kwargs, dedupe_key, owner)
            self.connection.set(key, info.id, ex=JOB_TIMEOUT_S)
        return info

    @_needs_redis
    def get(self, job_id: str) -> JobInfo:
        info = self._find(job_id)
        if info is None:
            return self._from_record(job_id)
        if info.state == "started" and reap_abandoned(self.connection, self.queues.values()):
            info = self._find(job_id) or info
        self._record(info)
        return info

    @_needs_redis
    def cancel(self, job_id: str) -> JobInfo:
        info = self.get(job_id)
        if not cancel_needed(info):
            return info
        if info.state == "started":
            send_stop_job_command(self.connection, job_id)
            return replace(info, message="cancel requested; the worker stops the job")
        job = self._fetch(job_id)
        with contextlib.suppress(InvalidJobOperation):  # it was canceled in between
            job.cancel()
        self.connection.expire(job.key, self.keep_ended_s)  # RQ keeps a canceled job until deleted
        return self.get(job_id)

    @_needs_redis
    def check(self) -> None:
        self.connection.ping()

    def close(self) -> None:
        if self._stop_reaper is not None:
            self._stop_reaper.set()
        self.connection.close()

    # -- helpers ------------------------------------------------------------------------------------------
    def _enqueue(self, kind: str, kwargs: dict, dedupe_key: str | None, owner: str | None) -> JobInfo:
        """Write the job's record, then queue it; a job that could not be queued was never issued."""
        info = JobInfo(uuid.uuid4().hex, kind, "queued", message="queued", created_at=time.time(), owner=owner)
        self.records.create(StoredJob(info, kwargs, dedupe_key, runner="rq"))
        try:
            job = self.queues[kind].enqueue_call(
                JOB_FUNCTIONS[kind],
                kwargs=kwargs,
                job_id=info.id,
                timeout=JOB_TIMEOUT_S,
                result_ttl=self.keep_ended_s,
                failure_ttl=self.keep_ended_s,
                retry=Retry(max=self.retries) if self.retries > 0 else None,
                meta={"kind": kind, "owner": owner, "progress": 0.0, "message": "queued"},
                description=f"curvefm {kind}",
                on_success=Callback(record_success),
                on_failure=Callback(record_failure),
                on_stopped=Callback(record_stopped),
            )
        except BaseException:
            self.records.delete(info.id)
            raise
        return self._info(job)

    def _from_record(self, job_id: str) -> JobInfo:
        """A job Redis does not know: as its record says, or ``lost`` if it had not ended."""
        stored = self.records.load(job_id)
        if stored is None:
            raise unknown_job(job_id)
        if stored.info.state in ENDED_STATES:
            return stored.info
        return self.records.lose(job_id, lost_reason(stored.info, QUEUE_LOST)) or stored.info

    def _record(self, info: JobInfo) -> None:
        """Bring the job's record in line with Redis when its state changed (workers record most changes
        themselves; this catches the rest: cancels, retries of jobs whose worker died)."""
        if self._recorded_states.get(info.id) == info.state:
            return
        if len(self._recorded_states) >= RECORDED_STATES_KEPT:
            self._recorded_states.clear()
        self._recorded_states[info.id] = info.state
        self.records.update(info.id, **{f.name: getattr(info, f.name) for f in fields(info)})

    def _fetch(self, job_id: str) -> Job:
        if not _JOB_ID.match(job_id):
            raise unknown_job(job_id)
        try:
            return Job.fetch(job_id, connection=self.connection, serializer=SERIALIZER)
        except NoSuchJobError:
            raise unknown_job(job_id) from None

    def _find(self, job_id: str) -> JobInfo | None:
        try:
            return self._info(self._fetch(job_id))
        except NotFound:
            return None

    def _info(self, job: Job) -> JobInfo:
        state = _STATES.get(job.get_status(refresh=True), "queued")
        meta = job.get_meta(refresh=True)
        return JobInfo(
            id=job.id,
            kind=meta.get("kind", "unknown"),
            state=state,
            progress=1.0 if state == "finished" else float(meta.get("progress", 0.0)),
            message={"finished": "finished", "canceled": "canceled"}.get(state, meta.get("message", "")),
            result=job.return_value() if state == "finished" else None,
            error=recorded_failure(meta) if state == "failed" else None,
            worker=job.worker_name or None,
            created_at=_timestamp(job.created_at),
            started_at=_timestamp(job.started_at),
            ended_at=_timestamp(job.ended_at),
            owner=meta.get("owner"),
        )


def record_success(job: Job, connection: Redis, result) -> None:
    """RQ's success callback, run by the worker before it tells Redis: the record has the result first."""
    finished = {"progress": 1.0, "message": "finished", "result": result, "ended_at": time.time()}
    _update_record(job, state="finished", **finished)


def record_failure(job: Job, connection: Redis, exc_type, exc: BaseException, tb) -> None:
    """RQ's failure callback, run by the worker when the job raised and by RQ's abandoned-job handling when
    its worker died: store the failure as data in ``job.meta["failure"]``, and in the record once no retry
    is left."""
    failure = worker_lost(job) if isinstance(exc, AbandonedJobError) else JobFailure.of(exc)
    job.get_meta(refresh=True)
    job.meta["failure"] = asdict(failure)
    job.save_meta()
    if not job.retries_left:
        _update_record(job, state="failed", message="failed", error=failure, ended_at=time.time())


def record_stopped(job: Job, connection: Redis) -> None:
    """RQ's stopped callback, run by the worker whose running job was canceled."""
    _update_record(job, state="canceled", message="canceled", ended_at=time.time())


def _update_record(job: Job, **changes) -> None:
    records = records_of(job.kwargs)
    if records is not None:
        records.update(job.id, **changes)


def worker_lost(job: Job) -> JobFailure:
    worker = f" ({job.worker_name})" if job.worker_name else ""
    return JobFailure(
        WORKER_LOST,
        f"the worker running this job{worker} died or lost contact (killed, out of memory, or its machine went "
        "down) and no retries were left",
    )


def recorded_failure(meta: dict) -> JobFailure:
    """The failure :func:`record_failure` stored, or a generic one where the job's process died before any
    callback could run (e.g. a work horse killed for memory while its worker lived on)."""
    if "failure" in meta:
        return JobFailure(**meta["failure"])
    return JobFailure(WORKER_LOST, "the process running this job ended without saying why (killed, or out of memory)")


def _timestamp(moment: datetime | None) -> float | None:
    if moment is None:
        return None
    return (moment if moment.tzinfo else moment.replace(tzinfo=UTC)).timestamp()
