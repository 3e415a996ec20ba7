"""The job queue as the API sees it: the :class:`JobQueue` interface, job states and what a job reports.

Two implementations run the job functions of :mod:`curvefm.workers.jobs` with the same states:
:class:`curvefm.workers.embedded.EmbeddedQueue` (threads of the API process, no Redis) and
:class:`curvefm.workers.rq_queue.RQQueue` (RQ on Redis, run by ``curvefm worker`` processes);
:func:`curvefm.workers.factory.make_queue` picks one. The service imports only this module and the factory.

States: ``queued``, ``started``, ``finished``, ``failed``, ``canceled`` and ``lost``: the queue lost the job
(Redis restarted without it, or the API running it in-process restarted); its ``message`` says why. Every job
also has a durable record in the records' database (:mod:`curvefm.workers.job_rows`), so an id the service issued
is never unknown. Progress is a fraction in [0, 1] with a message. A failed job reports a :class:`JobFailure`
(a kind and one readable line); tracebacks go to the logs. A lost, failed or canceled job can be run again
(:meth:`JobQueue.retry`).
"""

from __future__ import annotations

import time
import uuid
from abc import ABC, abstractmethod
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

from curvefm.errors import Conflict, CurvefmError, InternalError, InvalidInput, NotFound, disk_full_error, shown
from curvefm.workers.sizing import TIMEOUT_SETTINGS, JobDemand, JobSizing, job_demand

if TYPE_CHECKING:
    from sqlalchemy import Connection

    from curvefm.workers.job_rows import DbJobRecords

JobState = Literal["queued", "started", "finished", "failed", "canceled", "lost"]
ENDED_STATES: tuple[JobState, ...] = ("finished", "failed", "canceled", "lost")
RETRYABLE_STATES: tuple[JobState, ...] = ("lost", "failed", "canceled")
JOB_KINDS = ("basis", "refine")
"""What :meth:`JobQueue.submit` runs: ``curvefm.workers.jobs.JOB_FUNCTIONS[kind]``."""
WORKER_LOST = "worker_lost"
TIMED_OUT = "timeout"
KILLED = "killed"
KEEP_ENDED_S = 7 * 24 * 3600.0
"""How long an ended job's record is kept by default (the service's ``CURVEFM_JOB_TTL``)."""
Admission = Callable[[], AbstractContextManager["Connection"]]
"""Opens the write transaction that admits a job (e.g. :meth:`curvefm.records.usage.Quotas.admit`: the owner's
concurrent-jobs quota) and in which its record is written; the job is queued only once that committed."""


@dataclass(frozen=True)
class JobFailure:
    """Why a job failed.

    ``kind``: the ``code`` of the :class:`~curvefm.errors.CurvefmError` the job raised (``invalid``,
    ``not_found``, ``conflict``, ``too_large`` (also: its stated memory is over the worker's budget), ``internal``,
    ``disk_full``), ``internal`` for any other exception, ``timeout`` when it ran over its time limit, ``killed`` when
    the process running it was killed while its worker lived on (the kernel's OOM killer: the message says the
    signal and the memory it had reached), or ``worker_lost`` when the worker itself died. ``message``: one
    readable line.
    """

    kind: str
    message: str

    @classmethod
    def of(cls, exc: BaseException) -> JobFailure:
        exc = disk_full_error(exc) or exc
        if isinstance(exc, CurvefmError):
            return cls(exc.code, one_line(exc.message))
        return cls(InternalError.code, one_line(f"{type(exc).__name__}: {exc}"))


@dataclass(frozen=True)
class JobInfo:
    id: str
    kind: str
    state: JobState
    progress: float = 0.0
    message: str = ""
    result: dict | None = None
    error: JobFailure | None = None
    worker: str | None = None
    created_at: float | None = None
    started_at: float | None = None
    ended_at: float | None = None
    owner: str | None = None
    """The user who submitted it (None: submitted by no user, e.g. before users existed)."""


@dataclass(frozen=True)
class StoredJob:
    """A job as its record keeps it: what it reports, and what it takes to run it again."""

    info: JobInfo
    kwargs: dict
    dedupe_key: str | None = None
    runner: str | None = None
    """Who runs the job: ``rq`` (any worker on the queue), or the in-process executor that took it."""
    session_id: str | None = None
    """The session a refinement runs from (listed in its refinements)."""


class JobQueue(ABC):
    mode: str
    runner: str
    """What the records of this queue's jobs name as their runner (see :class:`StoredJob`)."""
    records: DbJobRecords
    sizing: JobSizing

    def submit(
        self,
        kind: str,
        kwargs: dict,
        dedupe_key: str | None = None,
        owner: str | None = None,
        *,
        admit: Admission | None = None,
        session_id: str | None = None,
    ) -> JobInfo:
        """Queue the job function of ``kind`` with ``kwargs`` (plain JSON values) for ``owner`` (a refinement of
        ``session_id``). While a job with the same ``dedupe_key`` is queued or running, return that job (whoever
        owns it) instead of starting another. ``admit``'s transaction (its check may refuse) writes the job's
        record, and the job is queued after it committed; a job that cannot be queued then leaves no record. The
        job states its time limit and peak memory from its meshes (:mod:`curvefm.workers.sizing`); one that no
        worker's memory budget could take is refused here (:class:`~curvefm.errors.ResourceLimit`)."""
        check_kind(kind)
        need = job_demand(kind, kwargs, self.sizing)
        self._check_room(kind, need)
        return self._submit(StoredJob(new_job(kind, owner), kwargs, dedupe_key, self.runner, session_id), admit, need)

    @abstractmethod
    def _check_room(self, kind: str, need: JobDemand) -> None:
        """Raise :class:`~curvefm.errors.ResourceLimit` when no runner of ``kind`` could give the job its memory."""

    @abstractmethod
    def _submit(self, job: StoredJob, admit: Admission | None, need: JobDemand) -> JobInfo:
        """Issue ``job`` as :meth:`submit` says (or answer the running duplicate of its ``dedupe_key``), with the
        time limit ``need`` states."""

    @abstractmethod
    def get(self, job_id: str) -> JobInfo:
        """The job's current state (``lost`` when the queue lost it); raises
        :class:`~curvefm.errors.NotFound` for ids the service never issued."""

    @abstractmethod
    def cancel(self, job_id: str) -> JobInfo:
        """Cancel a queued job at once, or ask a running one to stop; ended jobs raise a ``Conflict``."""

    @abstractmethod
    def check(self) -> None:
        """Raise :class:`~curvefm.errors.Unavailable` when the queue cannot take or report jobs now."""

    @abstractmethod
    def close(self) -> None:
        """Release threads and connections."""

    def retry(self, job_id: str, admit: Admission | None = None) -> JobInfo:
        """Submit a lost, failed or canceled job again (same kind, arguments, owner and session), admitted by
        ``admit``; return the new job. Retrying the same job while its retry is queued or running returns that
        retry."""
        info = self.get(job_id)
        if info.state not in RETRYABLE_STATES:
            raise Conflict(f"job {job_id} is {info.state}; only a lost, failed or canceled job can be retried")
        stored = self.records.load(job_id)
        if stored is None:
            raise Conflict(f"job {job_id} has no stored arguments to run again; send the original request again")
        key = stored.dedupe_key or f"retry:{job_id}"
        return self.submit(info.kind, stored.kwargs, key, info.owner, admit=admit, session_id=stored.session_id)


def timed_out(timeout_s: int, need: JobDemand | None) -> JobFailure:
    """The failure of a job that ran past its time limit of ``timeout_s``."""
    sized = f" for {need.describe()}" if need else ""
    return JobFailure(
        TIMED_OUT,
        f"the job ran longer than its time limit of {timeout_s} s{sized} and was stopped; the limit is scaled to "
        f"the job's meshes ({TIMEOUT_SETTINGS} set how)",
    )


def new_job(kind: str, owner: str | None) -> JobInfo:
    """A job about to be issued: a new id, queued now."""
    return JobInfo(uuid.uuid4().hex, kind, "queued", message="queued", created_at=time.time(), owner=owner)


def one_line(text: str) -> str:
    return " ".join(text.split())


def unknown_job(job_id: str) -> NotFound:
    return NotFound(f"no job with id '{shown(job_id)}' (finished jobs are forgotten after a while)")


def already_ended(info: JobInfo) -> Conflict:
    return Conflict(f"job {info.id} already {info.state}; there is nothing to cancel")


def cancel_needed(info: JobInfo) -> bool:
    """Whether a job is still to be canceled: not when it already was; a job that ended otherwise is a conflict."""
    if info.state == "canceled":
        return False
    if info.state in ENDED_STATES:
        raise already_ended(info)
    return True


def check_kind(kind: str) -> None:
    if kind not in JOB_KINDS:
        raise InvalidInput(f"unknown job kind '{kind}'; kinds are {', '.join(JOB_KINDS)}")
