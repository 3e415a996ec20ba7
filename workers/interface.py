"""The job queue as the API sees it: the :class:`JobQueue` interface, job states and what a job reports.

Two implementations run the job functions of :mod:`curvefm.workers.jobs` with the same states:
:class:`curvefm.workers.embedded.EmbeddedQueue` (threads of the API process, no Redis) and
:class:`curvefm.workers.rq_queue.RQQueue` (RQ on Redis, run by ``curvefm worker`` processes);
:func:`curvefm.workers.factory.make_queue` picks one. The service imports only this module and the factory.

States: ``queued``, ``started``, ``finished``, ``failed``, ``canceled``. Progress is a fraction in [0, 1] with a
message. A failed job reports a :class:`JobFailure` (a kind and one readable line); tracebacks go to the logs.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Literal

from curvefm.errors import Conflict, CurvefmError, InternalError, InvalidInput, NotFound

JobState = Literal["queued", "started", "finished", "failed", "canceled"]
ENDED_STATES: tuple[JobState, ...] = ("finished", "failed", "canceled")
JOB_KINDS = ("basis", "refine")
"""What :meth:`JobQueue.submit` runs: ``curvefm.workers.jobs.JOB_FUNCTIONS[kind]``."""
WORKER_LOST = "worker_lost"


@dataclass(frozen=True)
class JobFailure:
    """Why a job failed.

    ``kind``: the ``code`` of the :class:`~curvefm.errors.CurvefmError` the job raised (``invalid``,
    ``not_found``, ``conflict``, ``too_large``, ``internal``), ``internal`` for any other exception, or
    ``worker_lost`` when the process running it died. ``message``: one readable line.
    """

    kind: str
    message: str

    @classmethod
    def of(cls, exc: BaseException) -> JobFailure:
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


class JobQueue(ABC):
    mode: str

    @abstractmethod
    def submit(self, kind: str, kwargs: dict, dedupe_key: str | None = None) -> JobInfo:
        """Queue the job function of ``kind`` with ``kwargs``. While a job with the same ``dedupe_key`` is
        queued or running, return that job instead of starting another."""

    @abstractmethod
    def get(self, job_id: str) -> JobInfo:
        """The job's current state; raises :class:`~curvefm.errors.NotFound` for unknown ids."""

    @abstractmethod
    def cancel(self, job_id: str) -> JobInfo:
        """Cancel a queued job at once, or ask a running one to stop; ended jobs raise a ``Conflict``."""

    @abstractmethod
    def close(self) -> None:
        """Release threads and connections."""


def one_line(text: str) -> str:
    return " ".join(text.split())


def unknown_job(job_id: str) -> NotFound:
    return NotFound(f"no job with id '{job_id}' (finished jobs are forgotten after a while)")


def already_ended(info: JobInfo) -> Conflict:
    return Conflict(f"job {info.id} already {info.state}; there is nothing to cancel")


def check_kind(kind: str) -> None:
    if kind not in JOB_KINDS:
        raise InvalidInput(f"unknown job kind '{kind}'; kinds are {', '.join(JOB_KINDS)}")
