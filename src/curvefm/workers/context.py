"""What a running job function knows about itself: its id and where to report progress.

Job functions stay plain (importable, plain arguments) and open ``with running_job() as job:``. Under an RQ
worker this reports progress in ``job.meta`` and keeps a short-lived "alive" key fresh in Redis, so a worker
killed mid-job is noticed within seconds (see :mod:`curvefm.workers.reaper`). The key names the attempt
(RQ's execution id), so a stale key of an earlier attempt never vouches for a later one. A job that states more
memory than the worker's budget is refused before it starts. Under the embedded executor it uses the executor's
callback (which raises :class:`curvefm.progress.Cancelled` once the job is cancelled).
Under RQ it also keeps the job's durable record (:mod:`curvefm.workers.job_rows`) at "started" and at progress
milestones. Called directly, outside any queue, it reports nowhere.
"""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass

from curvefm.progress import Progress, no_progress
from curvefm.workers.job_rows import records_of

ALIVE_TTL_S = 8
"""A job whose alive key is older than this is considered abandoned by its worker."""
ALIVE_REFRESH_S = 2.0

worker_memory_budget: int | None = None
"""The memory budget of the ``curvefm worker`` this process is (or whose work horse it is); set at its start."""


@dataclass(frozen=True)
class JobContext:
    id: str
    progress: Progress


_embedded_job: ContextVar[JobContext | None] = ContextVar("curvefm_embedded_job", default=None)


def progress_fraction(fraction: float) -> float:
    return round(min(max(float(fraction), 0.0), 1.0), 4)


def alive_key(job_id: str, execution_id: str) -> str:
    return f"curvefm:alive:{job_id}:{execution_id}"


def execution_created_at(connection, job_id: str, execution_id: str) -> float | None:
    """When RQ registered this attempt (seconds since the epoch), or None once its record expired."""
    from rq.executions import Execution

    try:
        return Execution.fetch(execution_id, job_id, connection).created_at.timestamp()
    except ValueError:
        return None


def _current_execution_id(rq_job) -> str:
    """This attempt's execution: the newest of the job's entries in its started registry (RQ adds it just
    before it forks the work horse)."""
    from rq.registry import StartedJobRegistry

    registry = StartedJobRegistry(rq_job.origin, connection=rq_job.connection, serializer=rq_job.serializer)
    ids = [e for j, e in registry.get_job_and_execution_ids(cleanup=False) if j == rq_job.id]
    return max(ids, key=lambda e: execution_created_at(rq_job.connection, rq_job.id, e) or 0.0, default="")


@contextmanager
def embedded_job(context: JobContext) -> Iterator[None]:
    """Used by the in-process executor around a job function call."""
    token = _embedded_job.set(context)
    try:
        yield
    finally:
        _embedded_job.reset(token)


@contextmanager
def running_job() -> Iterator[JobContext]:
    embedded = _embedded_job.get()
    if embedded is not None:
        yield embedded
        return
    from rq import get_current_job

    rq_job = get_current_job()
    if rq_job is None:
        yield JobContext(uuid.uuid4().hex, no_progress)
        return
    _refuse_over_budget(rq_job)
    with _alive(rq_job):
        yield JobContext(rq_job.id, _meta_progress(rq_job))


def _refuse_over_budget(rq_job) -> None:
    """Fail a job that states more memory than this worker's budget before it loads anything."""
    from curvefm.workers.sizing import over_budget, stated_demand

    need = stated_demand(rq_job.meta)
    whose = f"the budget of this worker ({rq_job.worker_name})"
    refusal = over_budget(need, worker_memory_budget, whose) if need else None
    if refusal is not None:
        raise refusal


def _meta_progress(rq_job) -> Progress:
    records = records_of(rq_job.kwargs)

    def report(fraction: float, message: str) -> None:
        rq_job.meta["progress"] = progress_fraction(fraction)
        rq_job.meta["message"] = message
        rq_job.save_meta()
        if records is not None:
            records.progress(rq_job.id, progress_fraction(fraction), message)

    rq_job.meta.pop("failure", None)  # recorded by an earlier attempt of a retried job
    if records is not None:
        started = {"progress": 0.0, "message": "started", "worker": rq_job.worker_name, "started_at": time.time()}
        records.update(rq_job.id, state="started", **started)
    report(0.0, "started")
    return report


@contextmanager
def _alive(rq_job) -> Iterator[None]:
    """Refresh the job's alive key from a thread. The key is left to expire, never deleted: between the
    function's return and RQ recording the result the job must not look abandoned."""
    from redis.exceptions import RedisError

    stop = threading.Event()
    connection, key = rq_job.connection, alive_key(rq_job.id, _current_execution_id(rq_job))

    def beat() -> None:
        while not stop.wait(ALIVE_REFRESH_S):
            try:
                connection.set(key, rq_job.worker_name or "worker", ex=ALIVE_TTL_S)
            except RedisError:  # a brief Redis outage must not kill the heartbeat; the next beat retries
                continue

    connection.set(key, rq_job.worker_name or "worker", ex=ALIVE_TTL_S)
    thread = threading.Thread(target=beat, name=f"alive-{rq_job.id}", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(timeout=5)
