"""Jobs whose worker died: noticed within seconds, then retried or failed by RQ.

RQ on its own notices a worker that died mid-job only when the job's registry entry expires (a minute or
more), then its abandoned-job handling retries the job (if retries are left) or fails it. We shorten that:
every running attempt keeps ``curvefm:alive:<job id>:<execution id>`` fresh (:mod:`curvefm.workers.context`),
and :func:`reap_abandoned` (run by every ``curvefm worker`` and by the API) expires the registry entry of any
started attempt whose key has lapsed, then lets RQ's own handling retry or fail the job (its failure callback
records why: :func:`curvefm.workers.rq_queue.record_failure`).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable

from redis import Redis
from rq import Queue
from rq.job import Job
from rq.registry import StartedJobRegistry
from rq.timeouts import TimerDeathPenalty

from curvefm.workers.connection import UNREACHABLE
from curvefm.workers.context import alive_key, execution_created_at

log = logging.getLogger("curvefm.workers")

STARTUP_GRACE_S = 15
"""An attempt gets this long to set its alive key (fork, setup) before it counts as abandoned."""
REAP_INTERVAL_S = 2.0


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
    # RQ runs the failure callback under a time limit; its default (SIGALRM) works in main threads only
    registry = StartedJobRegistry(queue=queue, death_penalty_class=TimerDeathPenalty)
    abandoned = [
        (job_id, execution_id)
        for job_id, execution_id in registry.get_job_and_execution_ids(cleanup=False)
        if _is_abandoned(connection, job_id, execution_id)
    ]
    for job_id, execution_id in abandoned:
        _note_abandoned(connection, queue, job_id)
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


def _note_abandoned(connection: Redis, queue: Queue, job_id: str) -> None:
    job = Job.fetch(job_id, connection=connection, serializer=queue.serializer)
    retrying = bool(job.retries_left)
    job.meta["message"] = f"worker {job.worker_name or '?'} died mid-job; " + (
        f"queued again ({(job.retries_left or 0) - 1} retries left after this one)" if retrying else "no retries left"
    )
    job.meta["progress"] = 0.0
    job.save_meta()


def start_reaper(
    connection: Redis, queues: list[Queue], interval_s: float = REAP_INTERVAL_S, also: Callable[[], None] = lambda: None
) -> threading.Event:
    """Run :func:`reap_abandoned`, then ``also``, every ``interval_s`` in a daemon thread; set the returned event to
    stop."""
    stop = threading.Event()

    def loop() -> None:
        while not stop.wait(interval_s):
            try:
                reap_abandoned(connection, queues)
                also()
            except UNREACHABLE as exc:  # Redis down: said once per interval, in one line
                log.warning("cannot look for abandoned jobs, Redis does not answer: %s", exc)
            except Exception:  # nothing may end the loop
                log.exception("reaping abandoned jobs failed; trying again in %.0f s", interval_s)

    threading.Thread(target=loop, name="curvefm-reaper", daemon=True).start()
    return stop
