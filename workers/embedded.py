"""The in-process executor: job functions run in a thread pool of the API process (no Redis needed).

Jobs live in memory and in their records (:mod:`curvefm.workers.records`). A job of an executor that is gone
(the API restarted, or stopped while the job was queued or running) is reported ``lost`` and can be retried.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
import uuid
from collections import OrderedDict
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

from curvefm.errors import Conflict
from curvefm.progress import Cancelled
from curvefm.workers.context import JobContext, embedded_job, progress_fraction
from curvefm.workers.interface import (
    ENDED_STATES,
    KEEP_ENDED_S,
    JobFailure,
    JobInfo,
    JobQueue,
    cancel_needed,
    check_kind,
    unknown_job,
)
from curvefm.workers.jobs import JOB_FUNCTIONS
from curvefm.workers.records import JobRecords, StoredJob, lost_reason

log = logging.getLogger("curvefm.workers")

RESTARTED = "the service restarted"
STOPPED = "the service stopped"


class EmbeddedQueue(JobQueue):
    """Runs jobs in threads of this process; their records go under ``data_dir``. An ended job leaves memory
    ``keep_ended_s`` after it ended, or when more than :attr:`KEEP_ENDED` jobs have ended."""

    mode = "embedded"
    KEEP_ENDED = 1000

    def __init__(self, data_dir: str | Path, max_workers: int = 2, keep_ended_s: float = KEEP_ENDED_S):
        self.records = JobRecords(data_dir)
        self.keep_ended_s = keep_ended_s
        self.runner = f"embedded:{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:8]}"
        self._executor = ThreadPoolExecutor(max_workers=max_workers, thread_name_prefix="curvefm-job")
        self._lock = threading.Lock()
        self._jobs: OrderedDict[str, JobInfo] = OrderedDict()
        self._futures: dict[str, Future] = {}
        self._cancel_requested: set[str] = set()
        self._dedupe: dict[str, str] = {}
        self._closing = False
        for stored in self.records.unended():
            self._lose_if_orphaned(stored)

    def submit(self, kind: str, kwargs: dict, dedupe_key: str | None = None, owner: str | None = None) -> JobInfo:
        check_kind(kind)
        with self._lock:
            existing = self._jobs.get(self._dedupe.get(dedupe_key, ""))
            if existing is not None and existing.state not in ENDED_STATES:
                return existing
            info = JobInfo(uuid.uuid4().hex, kind, "queued", message="queued", created_at=time.time(), owner=owner)
            self.records.create(StoredJob(info, kwargs, dedupe_key, self.runner))
            self._jobs[info.id] = info
            if dedupe_key is not None:
                self._dedupe[dedupe_key] = info.id
            self._forget_old_jobs()
            self._futures[info.id] = self._executor.submit(self._run, info.id, kind, kwargs)
        return info

    def get(self, job_id: str) -> JobInfo:
        with self._lock:
            self._forget_old_jobs()
            info = self._jobs.get(job_id)
        if info is not None:
            return info
        stored = self.records.load(job_id)
        if stored is None:
            raise unknown_job(job_id)
        return self._lose_if_orphaned(stored)

    def cancel(self, job_id: str) -> JobInfo:
        with self._lock:
            info = self._jobs.get(job_id)
            if info is not None and cancel_needed(info):
                return self._cancel_mine(info)
        info = info or self.get(job_id)
        if cancel_needed(info):  # not ended, and run by another process of the service
            raise Conflict(f"job {job_id} runs in another process of the service, which alone can cancel it")
        return info

    def check(self) -> None:
        return None  # the executor is this process

    def close(self) -> None:
        """Stop: queued jobs are lost at once, running ones at their next progress step."""
        with self._lock:
            self._closing = True
            for job_id, info in list(self._jobs.items()):
                if info.state == "queued" and self._futures[job_id].cancel():
                    self._set(job_id, state="lost", message=lost_reason(info, STOPPED), ended_at=time.time())
        self._executor.shutdown(wait=True, cancel_futures=True)

    # -- running ------------------------------------------------------------------------------------------
    def _run(self, job_id: str, kind: str, kwargs: dict) -> None:
        with self._lock:
            self._set(job_id, state="started", message="started", started_at=time.time())
        try:
            with embedded_job(JobContext(job_id, lambda fraction, message: self._progress(job_id, fraction, message))):
                result = JOB_FUNCTIONS[kind](**kwargs)
        except Cancelled:
            if job_id in self._cancel_requested:
                self._end(job_id, state="canceled", message="canceled")
            else:  # the service is stopping
                self._end(job_id, state="lost", message=lost_reason(self._jobs[job_id], STOPPED))
        except Exception as exc:
            log.warning("job %s (%s) failed", job_id, kind, exc_info=True)
            self._end(job_id, state="failed", message="failed", error=JobFailure.of(exc))
        else:
            self._end(job_id, state="finished", progress=1.0, message="finished", result=result)

    def _progress(self, job_id: str, fraction: float, message: str) -> None:
        with self._lock:
            if self._closing or job_id in self._cancel_requested:
                raise Cancelled(f"job {job_id} was canceled")
            self._set(job_id, progress=progress_fraction(fraction), message=message)
        self.records.progress(job_id, progress_fraction(fraction), message)

    def _end(self, job_id: str, **changes) -> None:
        with self._lock:
            self._set(job_id, ended_at=time.time(), **changes)
            self._futures.pop(job_id, None)
            self._cancel_requested.discard(job_id)

    def _set(self, job_id: str, **changes) -> JobInfo:
        """Change the job in memory, and in its record when its state changes."""
        self._jobs[job_id] = replace(self._jobs[job_id], **changes)
        if "state" in changes:
            self.records.update(job_id, **changes)
        return self._jobs[job_id]

    def _cancel_mine(self, info: JobInfo) -> JobInfo:
        if self._futures[info.id].cancel():
            del self._futures[info.id]
            return self._set(info.id, state="canceled", message="canceled before it started", ended_at=time.time())
        self._cancel_requested.add(info.id)
        return replace(info, message="cancel requested; the job stops at its next progress step")

    def _forget_old_jobs(self) -> None:
        """Keep the newest ``KEEP_ENDED`` ended jobs in memory, none older than ``keep_ended_s``; others are
        answered from their records (until those expire too)."""
        ended = [j for j, info in self._jobs.items() if info.state in ENDED_STATES]
        too_many = set(ended[: max(len(ended) - self.KEEP_ENDED, 0)])
        expired = time.time() - self.keep_ended_s
        for job_id in ended:
            if job_id in too_many or (self._jobs[job_id].ended_at or expired) < expired:
                del self._jobs[job_id]

    # -- jobs of other executors ------------------------------------------------------------------------------
    def _lose_if_orphaned(self, stored: StoredJob) -> JobInfo:
        """A record's job as it stands: ``lost`` when it has not ended and the executor that took it is gone."""
        if stored.info.state in ENDED_STATES or self._runner_alive(stored.runner):
            return stored.info
        return self.records.lose(stored.info.id, lost_reason(stored.info, RESTARTED)) or stored.info

    def _runner_alive(self, runner: str | None) -> bool:
        """Whether the executor named ``runner`` may still run its jobs: this one, or a live process of this
        machine (another machine's cannot be checked, so its records are believed)."""
        if runner == self.runner:
            return True
        kind, _, rest = (runner or "").partition(":")
        host, _, pid = rest.partition(":")
        pid = pid.partition(":")[0]
        if kind != "embedded" or not pid.isdigit():
            return False  # a job of the RQ queue, whose Redis this service no longer uses
        if host != socket.gethostname():
            return True
        return int(pid) != os.getpid() and _process_exists(int(pid))


def _process_exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
