"""The in-process executor: job functions run in a thread pool of the API process (no Redis needed).

Jobs live in memory and in their records (:mod:`curvefm.workers.job_rows`). A job of an executor that is gone
(the API restarted, or stopped while the job was queued or running) is reported ``lost`` and can be retried.

Memory leads: a job whose record cannot be written (a full disk) fails, or ends as it would, in memory at once, and
its record is written once the database takes it again (every ``RECORD_RETRY_S``), so it never stays running for
ever, holding its user's job slot and absorbing new requests for the same work.
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

from curvefm.errors import Conflict, DiskFull
from curvefm.progress import Cancelled
from curvefm.records.webhooks import DEFAULT_LOG_SIZE
from curvefm.workers.context import JobContext, embedded_job, progress_fraction
from curvefm.workers.interface import (
    ENDED_STATES,
    KEEP_ENDED_S,
    Admission,
    JobFailure,
    JobInfo,
    JobQueue,
    cancel_needed,
    timed_out,
    unknown_job,
)
from curvefm.workers.job_rows import RECORD_ERRORS, DbJobRecords, StoredJob, lost_reason, note_unrecorded
from curvefm.workers.jobs import JOB_FUNCTIONS
from curvefm.workers.sizing import DEFAULT_SIZING, JobDemand, JobSizing, over_budget

log = logging.getLogger("curvefm.workers")

RESTARTED = "the service restarted"
STOPPED = "the service stopped"
RECORD_RETRY_S = 2.0
"""How often the records of ended jobs that could not be written are tried again."""


class TimedOut(Exception):
    """Raised at a job's progress step once it has run past its time limit (a thread cannot be stopped sooner)."""


class EmbeddedQueue(JobQueue):
    """Runs jobs in threads of this process; their records go under ``data_dir``. An ended job leaves memory
    ``keep_ended_s`` after it ended, or when more than :attr:`KEEP_ENDED` jobs have ended. A job that states more
    memory than ``memory_budget`` is refused; one that runs past its time limit fails at its next progress step."""

    mode = "embedded"
    KEEP_ENDED = 1000

    def __init__(
        self,
        data_dir: str | Path,
        max_workers: int = 2,
        keep_ended_s: float = KEEP_ENDED_S,
        sizing: JobSizing = DEFAULT_SIZING,
        memory_budget: int | None = None,
        webhook_log_size: int = DEFAULT_LOG_SIZE,
    ):
        self.records = DbJobRecords(data_dir, webhook_log_size=webhook_log_size)
        self.sizing = sizing
        self.memory_budget = memory_budget
        self.keep_ended_s = keep_ended_s
        self.runner = f"embedded:{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:8]}"
        self._executor = ThreadPoolExecutor(max_workers=max_workers, thread_name_prefix="curvefm-job")
        self._lock = threading.Lock()
        self._jobs: OrderedDict[str, JobInfo] = OrderedDict()
        self._futures: dict[str, Future] = {}
        self._cancel_requested: set[str] = set()
        self._dedupe: dict[str, str] = {}
        self._deadlines: dict[str, float] = {}
        self._unrecorded: dict[str, dict] = {}  # ended jobs' changes their records still lack
        self._record_retry: threading.Timer | None = None
        self._closing = False
        for stored in self.records.unended():
            self._lose_if_orphaned(stored)

    def _check_room(self, kind: str, need: JobDemand) -> None:
        refusal = over_budget(need, self.memory_budget, "the budget of the service's in-process executor")
        if refusal is not None:
            raise refusal

    def _submit(self, job: StoredJob, admit: Admission | None, need: JobDemand) -> JobInfo:
        with self._lock:
            self._write_unrecorded()
            existing = self._running_duplicate(job.dedupe_key)
            with self.records.admitted(admit) as conn:  # the owner's quota and the job's record: one transaction
                if existing is not None:
                    return existing
                self.records.create(job, conn)
            self._start(job, need)  # committed: the job's thread updates its record
        return job.info

    def _running_duplicate(self, dedupe_key: str | None) -> JobInfo | None:
        """The queued or running job of ``dedupe_key``, in this process or (if it lives) another one's."""
        if dedupe_key is None:
            return None
        existing = self._jobs.get(self._dedupe.get(dedupe_key, ""))
        if existing is not None and existing.state not in ENDED_STATES:
            return existing
        elsewhere = self.records.active_stored(dedupe_key)
        info = self._lose_if_orphaned(elsewhere) if elsewhere is not None else None
        return info if info is not None and info.state not in ENDED_STATES else None

    def _start(self, job: StoredJob, need: JobDemand) -> None:
        info = job.info
        try:
            future = self._executor.submit(self._run, info.id, info.kind, job.kwargs, need)
        except BaseException:  # the executor is shut down: the job was never issued
            self.records.delete(info.id)
            raise
        self._jobs[info.id] = info
        self._futures[info.id] = future
        if job.dedupe_key is not None:
            self._dedupe[job.dedupe_key] = info.id
        self._forget_old_jobs()

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
            if self._record_retry is not None:
                self._record_retry.cancel()
            for job_id, info in list(self._jobs.items()):
                if info.state == "queued" and self._futures[job_id].cancel():
                    self._set(job_id, state="lost", message=lost_reason(info, STOPPED), ended_at=time.time())
        self._executor.shutdown(wait=True, cancel_futures=True)

    # -- running ------------------------------------------------------------------------------------------
    def _run(self, job_id: str, kind: str, kwargs: dict, need: JobDemand) -> None:
        try:
            with self._lock:
                self._set(job_id, state="started", message="started", started_at=time.time())
                self._deadlines[job_id] = time.monotonic() + need.timeout_s
            with embedded_job(JobContext(job_id, lambda fraction, message: self._progress(job_id, fraction, message))):
                result = JOB_FUNCTIONS[kind](**kwargs)
        except Cancelled:
            if job_id in self._cancel_requested:
                self._end(job_id, state="canceled", message="canceled")
            else:  # the service is stopping
                self._end(job_id, state="lost", message=lost_reason(self._jobs[job_id], STOPPED))
        except TimedOut:
            self._end(job_id, state="failed", message="failed", error=timed_out(need.timeout_s, need))
        except Exception as exc:
            self._fail(job_id, kind, exc)
        else:
            self._end(job_id, state="finished", progress=1.0, message="finished", result=result)

    def _fail(self, job_id: str, kind: str, exc: Exception) -> None:
        failure = JobFailure.of(exc)
        if failure.kind == DiskFull.code:  # a known cause, named in the failure: no traceback
            log.warning("job %s (%s) failed: %s", job_id, kind, failure.message)
        else:
            log.warning("job %s (%s) failed", job_id, kind, exc_info=True)
        self._end(job_id, state="failed", message="failed", error=failure)

    def _progress(self, job_id: str, fraction: float, message: str) -> None:
        with self._lock:
            if self._closing or job_id in self._cancel_requested:
                raise Cancelled(f"job {job_id} was canceled")
            if time.monotonic() > self._deadlines[job_id]:
                raise TimedOut
            self._set(job_id, progress=progress_fraction(fraction), message=message)
        self.records.progress(job_id, progress_fraction(fraction), message)

    def _end(self, job_id: str, **changes) -> None:
        with self._lock:
            self._set(job_id, ended_at=time.time(), **changes)
            self._futures.pop(job_id, None)
            self._deadlines.pop(job_id, None)
            self._cancel_requested.discard(job_id)

    def _set(self, job_id: str, **changes) -> JobInfo:
        """Change the job in memory, and in its record when its state changes. A record that cannot be written
        raises, unless the job ended: then it is written later (:meth:`_write_unrecorded`)."""
        info = self._jobs[job_id] = replace(self._jobs[job_id], **changes)
        if "state" in changes:
            try:
                self.records.update(job_id, **changes)
            except RECORD_ERRORS as exc:
                if info.state not in ENDED_STATES:
                    raise
                self._defer_record(job_id, changes, exc)
        return info

    def _defer_record(self, job_id: str, changes: dict, exc: Exception) -> None:
        note_unrecorded(job_id, changes["state"], exc)
        self._unrecorded.setdefault(job_id, {}).update(changes)
        self._schedule_record_retry()

    def _schedule_record_retry(self) -> None:
        if self._record_retry is None and not self._closing:
            self._record_retry = threading.Timer(RECORD_RETRY_S, self._retry_unrecorded)
            self._record_retry.daemon = True
            self._record_retry.start()

    def _retry_unrecorded(self) -> None:
        with self._lock:
            self._record_retry = None
            self._write_unrecorded()
            if self._unrecorded:
                self._schedule_record_retry()

    def _write_unrecorded(self) -> None:
        """Write the changes that ended jobs' records lack, oldest first, until one fails (called with the lock)."""
        for job_id, changes in list(self._unrecorded.items()):
            try:
                self.records.update(job_id, **changes)
            except RECORD_ERRORS:
                return
            del self._unrecorded[job_id]

    def _cancel_mine(self, info: JobInfo) -> JobInfo:
        if self._futures[info.id].cancel():
            del self._futures[info.id]
            return self._set(info.id, state="canceled", message="canceled before it started", ended_at=time.time())
        self._cancel_requested.add(info.id)
        return replace(info, message="cancel requested; the job stops at its next progress step")

    def _forget_old_jobs(self) -> None:
        """Keep the newest ``KEEP_ENDED`` ended jobs in memory, none older than ``keep_ended_s``; others are
        answered from their records (until those expire too)."""
        ended = [j for j, info in self._jobs.items() if info.state in ENDED_STATES and j not in self._unrecorded]
        too_many = set(ended[: max(len(ended) - self.KEEP_ENDED, 0)])
        expired = time.time() - self.keep_ended_s
        for job_id in ended:
            if job_id in too_many or (self._jobs[job_id].ended_at or expired) < expired:
                del self._jobs[job_id]

    # -- jobs of other executors ------------------------------------------------------------------------------
    def _lose_if_orphaned(self, stored: StoredJob) -> JobInfo:
        """A record's job as it stands: ``lost`` when it has not ended and the executor that took it is gone; a job
        of this executor as it stands in memory (ahead of its record when that could not be written)."""
        known = self._jobs.get(stored.info.id) if stored.runner == self.runner else None
        if known is not None:
            return known
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
