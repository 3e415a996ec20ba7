"""Jobs on RQ (Redis Queue): enqueueing, status, cancelling, and why a job failed.

Queue names are ``<prefix>curvefm-basis`` and ``<prefix>curvefm-refine`` (``CURVEFM_QUEUE_PREFIX``, empty by
default, lets several deployments or test runs share one Redis). Everything crosses Redis as JSON
(:data:`curvefm.workers.connection.SERIALIZER`): workers must use it too, as ``curvefm worker`` does. Every job
carries callbacks that keep its durable record (:mod:`curvefm.workers.job_rows`) and, on failure, store its kind
and message as data in ``job.meta["failure"]``, never read back from traceback text. Jobs whose worker died
are handled by :mod:`curvefm.workers.reaper`. While Redis does not answer, every operation raises
:class:`~curvefm.errors.Unavailable`. Each job's RQ timeout is the time limit it states
(:mod:`curvefm.workers.sizing`), and its ``meta["demand"]`` what it states, which its worker checks against its budget.
Its ``meta["webhook_log_size"]`` is the API's ``CURVEFM_WEBHOOK_LOG_SIZE``, which the worker that records the end of
a run's last job keeps the webhooks' delivery logs to.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import re
import signal
import threading
import time
from dataclasses import asdict, fields, replace
from datetime import UTC, datetime
from pathlib import Path

from redis import Redis
from rq import Callback, Queue, Retry, Worker
from rq.command import send_stop_job_command
from rq.exceptions import AbandonedJobError, InvalidJobOperation, NoSuchJobError
from rq.job import Job, JobStatus
from rq.timeouts import JobTimeoutException
from rq.utils import now

from curvefm.errors import NotFound, ResourceLimit, Unavailable
from curvefm.records.webhooks import DEFAULT_LOG_SIZE
from curvefm.workers.connection import SERIALIZER, UNREACHABLE, connect
from curvefm.workers.interface import (
    ENDED_STATES,
    JOB_KINDS,
    KEEP_ENDED_S,
    KILLED,
    TIMED_OUT,
    WORKER_LOST,
    Admission,
    JobFailure,
    JobInfo,
    JobQueue,
    JobState,
    cancel_needed,
    one_line,
    timed_out,
    unknown_job,
)
from curvefm.workers.job_rows import (
    RECORD_ERRORS,
    DbJobRecords,
    StoredJob,
    lost_reason,
    note_unrecorded,
    records_of,
)
from curvefm.workers.jobs import JOB_FUNCTIONS
from curvefm.workers.reaper import reap_abandoned, start_reaper
from curvefm.workers.session_events import announce_refinement_end
from curvefm.workers.sizing import (
    DEFAULT_SIZING,
    MEMORY_SETTING,
    JobDemand,
    JobSizing,
    gigabytes,
    over_budget,
    stated_demand,
)

log = logging.getLogger("curvefm.workers")

DEDUPE_TTL_S = 3 * 3600
"""How long a deduplicated job's key is kept at least (and at least its time limit)."""
BUDGET_FIELD = "curvefm_memory"
"""The field of an RQ worker's Redis hash that states its memory budget in bytes (``curvefm worker`` sets it)."""
NOT_RETRIED = (TIMED_OUT, ResourceLimit.code)
"""Failures that running the job again would only repeat."""
RECORDED_STATES_KEPT = 10_000
QUEUE_LOST = "the job queue (Redis) no longer knows this job (it restarted without its data, or was emptied)"
REDIS_DOWN = (
    "the job queue (Redis) does not answer, so jobs can be neither submitted nor followed until it is back; "
    "curve edits, maps and transfers still work"
)

_STATES: dict[JobStatus, JobState] = {
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
    runner = "rq"

    def __init__(
        self,
        redis_url: str,
        data_dir: str | Path,
        prefix: str = "",
        retries: int = 1,
        keep_ended_s: float = KEEP_ENDED_S,
        sizing: JobSizing = DEFAULT_SIZING,
        webhook_log_size: int = DEFAULT_LOG_SIZE,
    ):
        self.connection = connect(redis_url)
        self.sizing = sizing
        self.records = DbJobRecords(data_dir, webhook_log_size=webhook_log_size)
        self.webhook_log_size = webhook_log_size
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
        """Hand jobs of dead workers to RQ's retry-or-fail handling every ``interval_s``, and bring records up to
        date, until :meth:`close`."""
        queues = list(self.queues.values())
        self._stop_reaper = start_reaper(self.connection, queues, interval_s, also=self._catch_up_records)

    @_needs_redis
    def _check_room(self, kind: str, need: JobDemand) -> None:
        """Refuse a job that none of its queue's live workers could take; with no worker known (none started yet,
        or started by another program) the job waits for one."""
        queue = self.queues[kind]
        budgets = [self.connection.hget(worker.key, BUDGET_FIELD) for worker in Worker.all(queue=queue)]
        if not budgets or None in budgets:
            return
        largest = max(int(budget) for budget in budgets if budget is not None)
        whose = f"the largest budget of the {len(budgets)} workers on queue {queue.name}"
        refusal = over_budget(need, largest, whose)
        if refusal is not None:
            raise refusal

    @_needs_redis
    def _submit(self, job: StoredJob, admit: Admission | None, need: JobDemand) -> JobInfo:
        dedupe_key = job.dedupe_key
        if dedupe_key is None:
            return self._enqueue(job, admit, need)
        key = self._dedupe_prefix + dedupe_key
        with self.connection.lock(key + ":lock", timeout=30, blocking_timeout=30):
            existing = self.connection.get(key)
            info = self._find(existing.decode() if isinstance(existing, bytes) else existing) if existing else None
            if info is not None and info.state not in ENDED_STATES:
                with self.records.admitted(admit):  # admitted as a new job would be
                    return info
            info = self._enqueue(job, admit, need)
            self.connection.set(key, info.id, ex=max(DEDUPE_TTL_S, need.timeout_s))
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
    def _enqueue(self, job: StoredJob, admit: Admission | None, need: JobDemand) -> JobInfo:
        """Write the job's record in the transaction that admits it, then (committed) queue it; a job that could
        not be queued was never issued."""
        info, kind = job.info, job.info.kind
        with self.records.admitted(admit) as conn:
            self.records.create(job, conn)
        try:
            queued = self.queues[kind].enqueue_call(
                JOB_FUNCTIONS[kind],
                kwargs=job.kwargs,
                job_id=info.id,
                timeout=need.timeout_s,
                result_ttl=self.keep_ended_s,
                failure_ttl=self.keep_ended_s,
                retry=Retry(max=self.retries) if self.retries > 0 else None,
                meta={
                    "kind": kind,
                    "owner": info.owner,
                    "progress": 0.0,
                    "message": "queued",
                    "demand": asdict(need),
                    "webhook_log_size": self.webhook_log_size,
                },
                description=f"curvefm {kind}",
                on_success=Callback(record_success),
                on_failure=Callback(record_failure),
                on_stopped=Callback(record_stopped),
            )
        except BaseException:
            self.records.delete(info.id)
            raise
        return self._info(queued)

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
        try:
            self.records.update(info.id, **{f.name: getattr(info, f.name) for f in fields(info)})
        except RECORD_ERRORS as exc:  # Redis has the truth: answer it, write the record later
            note_unrecorded(info.id, info.state, exc)
            return
        if len(self._recorded_states) >= RECORDED_STATES_KEPT:
            self._recorded_states.clear()
        self._recorded_states[info.id] = info.state

    def _catch_up_records(self) -> None:
        """Records left behind Redis (a worker could not write a job's end: a full disk) are brought in line."""
        try:
            unended = self.records.unended()
        except RECORD_ERRORS:
            return  # the database does not answer now: /health and every request say so; next round
        for stored in unended:
            info = self._find(stored.info.id)
            if info is not None and info.state in ENDED_STATES:
                self._record(info)

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
    announce_refinement_end(job, connection, "finished")


def record_failure(job: Job, connection: Redis, exc_type, exc: BaseException, tb) -> None:
    """RQ's failure callback, run by the worker when the job raised and by RQ's abandoned-job handling when
    its worker died: store the failure as data in ``job.meta["failure"]``, and in the record once no retry
    is left."""
    store_failure(job, failure_of(job, exc))


def failure_of(job: Job, exc: BaseException) -> JobFailure:
    if isinstance(exc, AbandonedJobError):
        return worker_lost(job)
    if isinstance(exc, JobTimeoutException):
        return job_timed_out(job)
    return JobFailure.of(exc)


def store_failure(job: Job, failure: JobFailure) -> None:
    """Keep ``failure`` in the job's meta, and in its record once no retry is left (none for a failure that a
    retry would repeat)."""
    if failure.kind in NOT_RETRIED:
        job.retries_left = 0
    job.get_meta(refresh=True)
    job.meta["failure"] = asdict(failure)
    job.save_meta()
    if not job.retries_left:
        _update_record(job, state="failed", message="failed", error=failure, ended_at=time.time())
        announce_refinement_end(job, job.connection, "failed")


def job_timed_out(job: Job) -> JobFailure:
    return timed_out(round(job.timeout or 0), stated_demand(job.meta))


def record_stopped(job: Job, connection: Redis) -> None:
    """RQ's stopped callback, run by the worker whose running job was canceled."""
    _update_record(job, state="canceled", message="canceled", ended_at=time.time())
    announce_refinement_end(job, connection, "canceled")


def _update_record(job: Job, **changes) -> None:
    records = records_of(job.kwargs, job.meta.get("webhook_log_size", DEFAULT_LOG_SIZE))
    if records is None:
        return
    try:
        records.update(job.id, **changes)
    except RECORD_ERRORS as exc:  # Redis has the job's end; the API writes the record from it later
        note_unrecorded(job.id, changes["state"], exc)


def worker_lost(job: Job) -> JobFailure:
    worker = f" ({job.worker_name})" if job.worker_name else ""
    return JobFailure(
        WORKER_LOST,
        f"the worker running this job{worker} died or lost contact (killed, out of memory, or its machine went "
        "down) and no retries were left",
    )


def horse_killed(job: Job, status: int, rusage, budget: int | None) -> JobFailure:
    """Why the process running ``job`` died while its worker lived on: past its time limit (the worker killed it),
    or ended by a signal (SIGKILL: most likely the kernel's OOM killer), with the memory it had reached."""
    if job.timeout and job.started_at and (now() - job.started_at).total_seconds() > job.timeout:
        return job_timed_out(job)
    reached = f" after it had reached {gigabytes(rusage.ru_maxrss * 1024)} of memory" if rusage else ""
    oom = _oom_hint(job, budget) if os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL else ""
    return JobFailure(KILLED, f"the process running this job {_ended(status)}{reached} while its worker lived on{oom}")


def _ended(status: int) -> str:
    if os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        return f"was killed by signal {number} ({signal.Signals(number).name})"
    return f"exited with status {os.WEXITSTATUS(status)}"


def _oom_hint(job: Job, budget: int | None) -> str:
    need = stated_demand(job.meta)
    stated = f"the job stated {gigabytes(need.memory_bytes)} for {need.describe()}; " if need else ""
    return (
        f": most likely the kernel's OOM killer ({stated}this worker's budget is {gigabytes(budget or 0)}: set "
        f"{MEMORY_SETTING} to the memory the worker really has)"
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
