"""``curvefm worker``: an RQ worker on the project's queues, plus the abandoned-job reaper."""

from __future__ import annotations

import os
from collections.abc import Sequence

from curvefm.errors import InvalidInput


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
    forked work horse starts without import delay.
    """
    from rq import Queue, Worker

    from curvefm.workers import jobs  # noqa: F401  (imported here so work horses inherit it)
    from curvefm.workers.connection import SERIALIZER, connect
    from curvefm.workers.reaper import start_reaper
    from curvefm.workers.rq_queue import queue_names

    url = redis_url or os.environ.get("CURVEFM_REDIS_URL")
    if not url:
        raise InvalidInput("a worker needs Redis: pass --redis-url or set CURVEFM_REDIS_URL")
    connection = connect(url, worker=True)  # a wrong or missing password is a one-line error here
    names = list(queues) if queues else list(queue_names(os.environ.get("CURVEFM_QUEUE_PREFIX", "")).values())
    rq_queues = [Queue(queue_name, connection=connection, serializer=SERIALIZER) for queue_name in names]
    stop_reaper = start_reaper(connection, rq_queues)
    try:
        worker = Worker(rq_queues, connection=connection, name=name, serializer=SERIALIZER)
        worker.work(burst=burst, logging_level=log_level)
    finally:
        stop_reaper.set()
