"""The in-process executor: job functions run in a thread pool of the API process (no Redis needed)."""

from __future__ import annotations

import logging
import threading
import time
import uuid
from collections import OrderedDict
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace

from curvefm.progress import Cancelled
from curvefm.workers.context import JobContext, embedded_job, progress_fraction
from curvefm.workers.interface import (
    ENDED_STATES,
    JobFailure,
    JobInfo,
    JobQueue,
    already_ended,
    check_kind,
    unknown_job,
)
from curvefm.workers.jobs import JOB_FUNCTIONS

log = logging.getLogger("curvefm.workers")


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
            log.warning("job %s (%s) failed", job_id, kind, exc_info=True)
            self._end(job_id, state="failed", message="failed", error=JobFailure.of(exc))
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
