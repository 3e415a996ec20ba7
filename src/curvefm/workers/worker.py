"""``curvefm worker``: an RQ worker on the project's queues, with a memory budget, plus the abandoned-job reaper."""

from __future__ import annotations

import logging
from collections.abc import Sequence

from curvefm.errors import InvalidInput
from curvefm.workers.settings import QueueSettings

log = logging.getLogger("curvefm.workers")


def worker_main(
    redis_url: str | None = None,
    queues: Sequence[str] | None = None,
    name: str | None = None,
    burst: bool = False,
    log_level: str = "INFO",
) -> None:
    """Run an RQ worker until it is stopped (or, with ``burst``, until the queues are empty). Jobs cross Redis
    as JSON. A Redis that refuses the password, or wants one, is a one-line error (``curvefm worker`` exits 2).

    ``redis_url`` defaults to ``CURVEFM_REDIS_URL``; ``queues`` to both project queues with the
    ``CURVEFM_QUEUE_PREFIX`` prefix (basis first). Job functions are imported before the first job so each
    forked work horse starts without import delay. The worker's memory budget (``CURVEFM_WORKER_MEMORY``, by
    default the memory available now) is stated in its Redis hash, for the API to refuse jobs no worker could take,
    and a job that states more is failed ``too_large`` before it loads anything.
    """
    from rq import Queue

    from curvefm.workers import context, jobs  # noqa: F401  (imported here so work horses inherit it)
    from curvefm.workers.connection import SERIALIZER, connect
    from curvefm.workers.reaper import start_reaper
    from curvefm.workers.rq_queue import queue_names
    from curvefm.workers.sizing import MEMORY_SETTING, gigabytes

    settings = QueueSettings()
    url = redis_url or settings.redis_url
    if not url:
        raise InvalidInput("a worker needs Redis: pass --redis-url or set CURVEFM_REDIS_URL")
    connection = connect(url, worker=True)  # a wrong or missing password is a one-line error here
    names = list(queues) if queues else list(queue_names(settings.queue_prefix).values())
    rq_queues = [Queue(queue_name, connection=connection, serializer=SERIALIZER) for queue_name in names]
    budget = context.worker_memory_budget = settings.memory_budget()
    log.info("memory budget %s (%s)", gigabytes(budget), MEMORY_SETTING)
    stop_reaper = start_reaper(connection, rq_queues)
    try:
        worker = budgeted_worker_class()(rq_queues, connection=connection, name=name, serializer=SERIALIZER)
        worker.work(burst=burst, logging_level=log_level)
    finally:
        stop_reaper.set()


def budgeted_worker_class():
    """RQ's forking worker that states its budget in Redis and says why a work horse that died was killed."""
    from rq import Worker

    from curvefm.workers import context
    from curvefm.workers.rq_queue import BUDGET_FIELD, horse_killed, store_failure

    class BudgetedWorker(Worker):
        def register_birth(self, *args, **kwargs) -> None:
            super().register_birth(*args, **kwargs)
            self.connection.hset(self.key, BUDGET_FIELD, str(context.worker_memory_budget))

        def handle_work_horse_killed(self, job, retpid, ret_val, rusage) -> None:
            super().handle_work_horse_killed(job, retpid, ret_val, rusage)
            store_failure(job, horse_killed(job, ret_val, rusage, context.worker_memory_budget))

    return BudgetedWorker
