"""Jobs on RQ (Redis Queue): enqueueing, status, cancelling, and the handling of jobs whose worker died.

Queue names are ``<prefix>curvefm-basis`` and ``<prefix>curvefm-refine`` (``CURVEFM_QUEUE_PREFIX``, empty by
default, lets several deployments or test runs share one Redis). A plain ``rq worker`` on those queues runs
the jobs too.

Dead workers. RQ on its own notices a worker that died mid-job only when the job's registry entry expires
(a minute or more), then its abandoned-job handling retries the job (if retries are left) or fails it. We
shorten that: every running attempt keeps ``curvefm:alive:<job id>:<execution id>`` fresh
(:mod:`curvefm.workers.context`), and :func:`reap_abandoned` (run by every ``curvefm worker`` and by the API)
expires the registry entry of any started attempt whose key has lapsed, then lets RQ's own handling retry or
fail the job.
"""

from __future__ import annotations

import contextlib
import logging
import re
import threading
import time
import uuid
from collections.abc import Iterable
from dataclasses import replace
from datetime import UTC, datetime

from redis import Redis
from rq import Queue, Retry
from rq.command import send_stop_job_command
from rq.exceptions import InvalidJobOperation, NoSuchJobError
from rq.job import Job, JobStatus
from rq.registry import StartedJobRegistry

from curvefm.errors import CurvefmError
from curvefm.workers.context import alive_key, execution_created_at
from curvefm.workers.queue import (
    ENDED_STATES,
    JOB_FUNCTIONS,
    JobInfo,
    JobQueue,
    already_ended,
    check_kind,
    unknown_job,
)

log = logging.getLogger("curvefm.workers")

JOB_TIMEOUT_S = 3 * 3600
KEEP_RESULTS_S = 7 * 24 * 3600
STARTUP_GRACE_S = 15
"""An attempt gets this long to set its alive key (fork, setup) before it counts as abandoned."""
REAP_INTERVAL_S = 2.0

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
    return {kind: f"{prefix}curvefm-{kind}" for kind in JOB_FUNCTIONS}


class RQQueue(JobQueue):
    mode = "redis"

    def __init__(self, redis_url: str, prefix: str = "", retries: int = 1):
        self.connection = Redis.from_url(redis_url)
        self.retries = retries
        self.queues = {kind: Queue(name, connection=self.connection) for kind, name in queue_names(prefix).items()}
        self._dedupe_prefix = f"curvefm:{prefix}dedupe:"

    def ping(self) -> None:
        self.connection.ping()

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
        )

    def _fetch(self, job_id: str) -> Job:
        if not _JOB_ID.match(job_id):
            raise unknown_job(job_id)
        try:
            return Job.fetch(job_id, connection=self.connection)
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
        exc = job.exc_info if state == "failed" else None
        return JobInfo(
            id=job.id,
            kind=meta.get("kind", "unknown"),
            state=state,
            progress=1.0 if state == "finished" else float(meta.get("progress", 0.0)),
            message={"finished": "finished", "canceled": "canceled"}.get(state, meta.get("message", "")),
            result=job.return_value() if state == "finished" else None,
            error=readable_failure(exc, job) if state == "failed" else None,
            traceback=exc,
            worker=job.worker_name or None,
            created_at=_timestamp(job.created_at),
            started_at=_timestamp(job.started_at),
            ended_at=_timestamp(job.ended_at),
        )


def readable_failure(exc: str | None, job: Job) -> str:
    """One line for people: the exception message, or why the job was abandoned."""
    if not exc:
        return "the job failed without a recorded reason"
    if "AbandonedJobError" in exc:
        worker = f" ({job.worker_name})" if job.worker_name else ""
        return (
            f"the worker running this job{worker} died or lost contact (killed, out of memory, or its "
            "machine went down) and no retries were left"
        )
    last = [line for line in exc.strip().splitlines() if line.strip()][-1]
    return re.sub(r"^curvefm\.errors\.\w+: ", "", last)


def _timestamp(moment: datetime | None) -> float | None:
    if moment is None:
        return None
    return (moment if moment.tzinfo else moment.replace(tzinfo=UTC)).timestamp()


# ----------------------------------------------------------------------------------------------------------
# Abandoned jobs


def reap_abandoned(connection: Redis, queues: Iterable[Queue]) -> list[str]:
    """Hand every started job whose alive key lapsed to RQ's abandoned-job handling; return their ids."""
    reaped = []
    for queue in queues:
        lock = f"curvefm:reaper:{queue.name}"
        if not connection.set(lock, "1", nx=True, ex=30):
            continue  # another process is reaping this queue right now
        try:
            reaped += _reap_queue(connection, queue)
        finally:
            connection.delete(lock)
    return reaped


def _reap_queue(connection: Redis, queue: Queue) -> list[str]:
    registry = StartedJobRegistry(queue=queue)
    abandoned = [
        (job_id, execution_id)
        for job_id, execution_id in registry.get_job_and_execution_ids(cleanup=False)
        if _is_abandoned(connection, job_id, execution_id)
    ]
    for job_id, execution_id in abandoned:
        _note_abandoned(connection, job_id)
        connection.zadd(registry.key, {f"{job_id}:{execution_id}": 1}, xx=True)  # expire it now
    if abandoned:
        registry.cleanup()
        log.warning("jobs abandoned by dead workers, retried or failed: %s", [j for j, _ in abandoned])
    return [job_id for job_id, _ in abandoned]


def _is_abandoned(connection: Redis, job_id: str, execution_id: str) -> bool:
    """This attempt's alive key lapsed, or was never set within the startup grace."""
    if connection.exists(alive_key(job_id, execution_id)):
        return False
    created = execution_created_at(connection, job_id, execution_id)
    return created is None or time.time() - created > STARTUP_GRACE_S


def _note_abandoned(connection: Redis, job_id: str) -> None:
    job = Job.fetch(job_id, connection=connection)
    retrying = bool(job.retries_left)
    job.meta["message"] = f"worker {job.worker_name or '?'} died mid-job; " + (
        f"queued again ({job.retries_left - 1} retries left after this one)" if retrying else "no retries left"
    )
    job.meta["progress"] = 0.0
    job.save_meta()


def start_reaper(connection: Redis, queues: list[Queue], interval_s: float = REAP_INTERVAL_S) -> threading.Event:
    """Run :func:`reap_abandoned` every ``interval_s`` in a daemon thread; set the returned event to stop."""
    stop = threading.Event()

    def loop() -> None:
        while not stop.wait(interval_s):
            try:
                reap_abandoned(connection, queues)
            except Exception:  # a Redis hiccup must not end the loop
                log.exception("reaping abandoned jobs failed; trying again in %.0f s", interval_s)

    threading.Thread(target=loop, name="curvefm-reaper", daemon=True).start()
    return stop
