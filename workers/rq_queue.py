"""Jobs on RQ (Redis Queue): enqueueing, status, cancelling, and why a job failed.

Queue names are ``<prefix>curvefm-basis`` and ``<prefix>curvefm-refine`` (``CURVEFM_QUEUE_PREFIX``, empty by
default, lets several deployments or test runs share one Redis). Everything crosses Redis as JSON
(:data:`curvefm.workers.connection.SERIALIZER`): workers must use it too, as ``curvefm worker`` does. Every
job carries :func:`record_failure` as its RQ failure callback: a failed job's kind and message are data in
``job.meta["failure"]``, never read back from traceback text. Jobs whose worker died are handled by
:mod:`curvefm.workers.reaper`.
"""

from __future__ import annotations

import contextlib
import re
import threading
import uuid
from dataclasses import asdict, replace
from datetime import UTC, datetime

from redis import Redis
from rq import Callback, Queue, Retry
from rq.command import send_stop_job_command
from rq.exceptions import AbandonedJobError, InvalidJobOperation, NoSuchJobError
from rq.job import Job, JobStatus

from curvefm.errors import CurvefmError
from curvefm.workers.connection import SERIALIZER, connect
from curvefm.workers.interface import (
    ENDED_STATES,
    JOB_KINDS,
    WORKER_LOST,
    JobFailure,
    JobInfo,
    JobQueue,
    already_ended,
    check_kind,
    unknown_job,
)
from curvefm.workers.jobs import JOB_FUNCTIONS
from curvefm.workers.reaper import reap_abandoned, start_reaper

JOB_TIMEOUT_S = 3 * 3600
KEEP_RESULTS_S = 7 * 24 * 3600

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


class RQQueue(JobQueue):
    mode = "redis"

    def __init__(self, redis_url: str, prefix: str = "", retries: int = 1):
        self.connection = connect(redis_url)
        self.retries = retries
        self.queues = {
            kind: Queue(name, connection=self.connection, serializer=SERIALIZER)
            for kind, name in queue_names(prefix).items()
        }
        self._dedupe_prefix = f"curvefm:{prefix}dedupe:"
        self._stop_reaper: threading.Event | None = None

    def start_reaper(self, interval_s: float) -> None:
        """Hand jobs of dead workers to RQ's retry-or-fail handling every ``interval_s``, until :meth:`close`."""
        self._stop_reaper = start_reaper(self.connection, list(self.queues.values()), interval_s)

    def submit(self, kind: str, kwargs: dict, dedupe_key: str | None = None) -> JobInfo:
        check_kind(kind)
        if dedupe_key is None:
            return self._info(self._enqueue(kind, kwargs))
        key = self._dedupe_prefix + dedupe_key
        with self.connection.lock(key + ":lock", timeout=30, blocking_timeout=30):
            existing = self.connection.get(key)
            if existing is not None:
                info = self._find(existing.decode())
                if info is not None and info.state not in ENDED_STATES:
                    return info
            job = self._enqueue(kind, kwargs)
            self.connection.set(key, job.id, ex=JOB_TIMEOUT_S)
        return self._info(job)

    def get(self, job_id: str) -> JobInfo:
        info = self._find(job_id)
        if info is None:
            raise unknown_job(job_id)
        if info.state == "started" and reap_abandoned(self.connection, self.queues.values()):
            info = self._find(job_id) or info
        return info

    def cancel(self, job_id: str) -> JobInfo:
        job = self._fetch(job_id)
        info = self._info(job)
        if info.state == "canceled":
            return info
        if info.state in ENDED_STATES:
            raise already_ended(info)
        if info.state == "started":
            send_stop_job_command(self.connection, job_id)
            return replace(info, message="cancel requested; the worker stops the job")
        with contextlib.suppress(InvalidJobOperation):  # it was canceled in between
            job.cancel()
        return self._info(self._fetch(job_id))

    def close(self) -> None:
        if self._stop_reaper is not None:
            self._stop_reaper.set()
        self.connection.close()

    # -- helpers ------------------------------------------------------------------------------------------
    def _enqueue(self, kind: str, kwargs: dict) -> Job:
        return self.queues[kind].enqueue_call(
            JOB_FUNCTIONS[kind],
            kwargs=kwargs,
            job_id=uuid.uuid4().hex,
            timeout=JOB_TIMEOUT_S,
            result_ttl=KEEP_RESULTS_S,
            failure_ttl=KEEP_RESULTS_S,
            retry=Retry(max=self.retries) if self.retries > 0 else None,
            meta={"kind": kind, "progress": 0.0, "message": "queued"},
            description=f"curvefm {kind}",
            on_failure=Callback(record_failure),
        )

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
        except CurvefmError:
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
        )


def record_failure(job: Job, connection: Redis, exc_type, exc: BaseException, tb) -> None:
    """RQ's failure callback, run by the worker when the job raised and by RQ's abandoned-job handling when
    its worker died: store the failure as data in ``job.meta["failure"]``."""
    failure = worker_lost(job) if isinstance(exc, AbandonedJobError) else JobFailure.of(exc)
    job.get_meta(refresh=True)
    job.meta["failure"] = asdict(failure)
    job.save_meta()


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
