"""``make_queue``: the job queue a service runs with, RQ on Redis or the in-process executor."""

from __future__ import annotations

from pathlib import Path

from curvefm.records.webhooks import DEFAULT_LOG_SIZE
from curvefm.workers.embedded import EmbeddedQueue
from curvefm.workers.interface import KEEP_ENDED_S, JobQueue
from curvefm.workers.sizing import DEFAULT_SIZING, JobSizing

API_REAP_INTERVAL_S = 5.0
"""How often the API looks for jobs of dead workers (the workers themselves look more often)."""


def make_queue(
    redis_url: str | None,
    data_dir: str | Path,
    prefix: str = "",
    retries: int = 1,
    embedded_workers: int = 2,
    keep_ended_s: float = KEEP_ENDED_S,
    sizing: JobSizing = DEFAULT_SIZING,
    memory_budget: int | None = None,
    webhook_log_size: int = DEFAULT_LOG_SIZE,
) -> JobQueue:
    """RQ on Redis when a URL is given (checked to answer, with its reaper of dead workers' jobs running until
    the queue is closed), else the in-process executor. Job records go under ``data_dir``. The queue forgets
    an ended job ``keep_ended_s`` after it ended (its record is the expiry's to delete). Jobs are sized by
    ``sizing``; the in-process executor refuses those over ``memory_budget`` (the workers have their own). A job's
    end that ends a run, recorded here, keeps each webhook's newest ``webhook_log_size`` deliveries."""
    if not redis_url:
        return EmbeddedQueue(data_dir, embedded_workers, keep_ended_s, sizing, memory_budget, webhook_log_size)
    from curvefm.workers.rq_queue import RQQueue  # needs redis and rq, which embedded mode does without

    queue = RQQueue(redis_url, data_dir, prefix, retries, keep_ended_s, sizing, webhook_log_size)
    queue.start_reaper(API_REAP_INTERVAL_S)
    return queue


def check_redis(redis_url: str) -> None:
    """Raise a one-line error now if the Redis at ``redis_url`` does not answer or refuses its password."""
    from curvefm.workers.connection import connect

    connect(redis_url).close()
