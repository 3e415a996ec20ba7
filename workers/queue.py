"""The job queue the API talks to: one interface, two implementations with the same job states.

* :class:`EmbeddedQueue` runs job functions in a thread pool inside the API process (no Redis needed).
* :class:`curvefm.workers.rq_queue.RQQueue` sends them to RQ on Redis, run by ``curvefm worker`` processes.

States: ``queued``, ``started``, ``finished``, ``failed``, ``canceled``. Progress is a fraction in [0, 1] with
a message. A failed job keeps its traceback and exposes a one-line readable ``error``.
"""

from __future__ import annotations

import threading
import time
import traceback
import uuid
from abc import ABC, abstractmethod
from collections import OrderedDict
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Literal

from curvefm.errors import Conflict, CurvefmError, InvalidInput, NotFound
from curvefm.progress import Cancelled
from curvefm.workers import jobs
from curvefm.workers.context import JobContext, embedded_job, progress_fraction

JobState = Literal["queued", "started", "finished", "failed", "canceled"]
ENDED_STATES = ("finished", "failed", "canceled")
JOB_FUNCTIONS = {"basis": jobs.compute_basis, "refine": jobs.refine}


@dataclass(frozen=True)
class JobInfo:
    id: str
    kind: str
    state: JobState
    progress: float = 0.0
    message: str = ""
    result: dict | None = None
    error: str | None = None
    traceback: str | None = None
    worker: str | None = None
    created_at: float | None = None
    started_at: float | None = None
    ended_at: float | None = None


class JobQueue(ABC):
    mode: str

    @abstractmethod
    def submit(self, kind: str, kwargs: dict, dedupe_key: str | None = None) -> JobInfo:
        """Queue ``JOB_FUNCTIONS[kind](**kwargs)``. While a job with the same ``dedupe_key`` is queued or
        running, return that job instead of starting another."""

    @abstractmethod
    def get(self, job_id: str) -> JobInfo:
        """The job's current state; raises :class:`~curvefm.errors.NotFound` for unknown ids."""

    @abstractmethod
    def cancel(self, job_id: str) -> JobInfo:
        """Cancel a queued job at once, or ask a running one to stop; ended jobs raise a ``Conflict``."""

    @abstractmethod
    def close(self) -> None:
        """Release threads and connections."""


def unknown_job(job_id: str) -> NotFound:
    return NotFound(f"no job with id '{job_id}' (finished jobs are forgotten after a while)")


def already_ended(info: JobInfo) -> Conflict:
    return Conflict(f"job {info.id} already {info.state}; there is nothing to cancel")


def check_kind(kind: str) -> None:
    if kind not in JOB_FUNCTIONS:
        raise InvalidInput(f"unknown job kind '{kind}'; kinds are {', '.join(JOB_FUNCTIONS)}")


def readable_error(exc: BaseException) -> str:
    if isinstance(exc, CurvefmError):
        return exc.message
    return f"{type(exc).__name__}: {exc}"


class EmbeddedQueue(JobQueue):
    """Runs jobs in threads of this process. Jobs live in memory: a restart forgets them (files stay)."""

    mode = "embedded"
    KEEP_ENDED = 1000

    def __init__(self, max_workers: int = 2):
        self._executor = ThreadPoolExecutor(max_workers=max_workers, thread_name_prefix="curvefm-job")
        self._lock = threading.Lock()
        self._jobs: OrderedDict[str, JobInfo] = OrderedDict()
        self._futures: dict[str, Future] = {}
        self._cancel_requested: set[str] = set()
        self._dedupe: dict[str, str] = {}

    def submit(self, kind: str, kwargs: dict, dedupe_key: str | None = None) -> JobInfo:
        check_kind(kind)
        with self._lock:
            existing = self._jobs.get(self._dedupe.get(dedupe_key, ""))
            if existing is not None and existing.state not in ENDED_STATES:
                return existing
            info = JobInfo(uuid.uuid4().hex, kind, "queued", message="queued", created_at=time.time())
            self._jobs[info.id] = info
            if dedupe_key is not None:
                self._dedupe[dedupe_key] = info.id
            self._forget_old_jobs()
            self._futures[info.id] = self._executor.submit(self._run, info.id, kind, kwargs)
        return info

    def get(self, job_id: str) -> JobInfo:
        with self._lock:
            if job_id not in self._jobs:
                raise unknown_job(job_id)
            return self._jobs[job_id]

    def cancel(self, job_id: str) -> JobInfo:
        with self._lock:
            info = self._jobs.get(job_id)
            if info is None:
                raise unknown_job(job_id)
            if info.state == "canceled":
                return info
            if info.state in ENDED_STATES:
                raise already_ended(info)
            if self._futures[job_id].cancel():
                del self._futures[job_id]
                return self._set(job_id, state="canceled", message="canceled before it started", ended_at=time.time())
            self._cancel_requested.add(job_id)
            return self._set(job_id, message="cancel requested; the job stops at its next progress step")

    def close(self) -> None:
        with self._lock:
            self._cancel_requested.update(j for j, info in self._jobs.items() if info.state not in ENDED_STATES)
        self._executor.shutdown(wait=True, cancel_futures=True)

    # -- running ------------------------------------------------------------------------------------------
    def _run(self, job_id: str, kind: str, kwargs: dict) -> None:
        with self._lock:
            self._set(job_id, state="started", message="started", started_at=time.time())
        try:
            with embedded_job(JobContext(job_id, lambda fraction, message: self._progress(job_id, fraction, message))):
                result = JOB_FUNCTIONS[kind](**kwargs)
        except Cancelled:
            self._end(job_id, state="canceled", message="canceled")
        except Exception as exc:
            self._end(
                job_id,
                state="failed",
                message="failed",
                error=readable_error(exc),
                traceback=traceback.format_exc(),
            )
        else:
            self._end(job_id, state="finished", progress=1.0, message="finished", result=result)

    def _progress(self, job_id: str, fraction: float, message: str) -> None:
        with self._lock:
            if job_id in self._cancel_requested:
                raise Cancelled(f"job {job_id} was canceled")
            self._set(job_id, progress=progress_fraction(fraction), message=message)

    def _end(self, job_id: str, **changes) -> None:
        with self._lock:
            self._set(job_id, ended_at=time.time(), **changes)
            self._futures.pop(job_id, None)
            self._cancel_requested.discard(job_id)

    def _set(self, job_id: str, **changes) -> JobInfo:
        self._jobs[job_id] = replace(self._jobs[job_id], **changes)
        return self._jobs[job_id]

    def _forget_old_jobs(self) -> None:
        ended = [j for j, info in self._jobs.items() if info.state in ENDED_STATES]
        for job_id in ended[: max(len(ended) - self.KEEP_ENDED, 0)]:
            del self._jobs[job_id]


def make_queue(redis_url: str | None, prefix: str = "", retries: int = 1, embedded_workers: int = 2) -> JobQueue:
    """RQ on Redis when a URL is given, else the in-process executor."""
    if not redis_url:
        return EmbeddedQueue(embedded_workers)
    from curvefm.workers.rq_queue import RQQueue

    return RQQueue(redis_url, prefix=prefix, retries=retries)
