"""Progress reporting shared by long computations, jobs and the CLI."""

from __future__ import annotations

import threading
from collections.abc import Callable

Progress = Callable[[float, str], None]
"""``progress(fraction, message)`` with ``fraction`` in [0, 1]. A job runner may raise
:class:`Cancelled` from inside it to stop the work between steps."""


class Cancelled(Exception):
    """Raised through a progress callback when the job was cancelled."""


def no_progress(fraction: float, message: str) -> None:
    return None


def scaled(progress: Progress, start: float, stop: float) -> Progress:
    """Map a sub-task's 0..1 onto ``start..stop`` of the parent's progress."""
    return lambda fraction, message: progress(start + (stop - start) * fraction, message)


def shared(progress: Progress, parts: int) -> list[Progress]:
    """Progress callbacks for ``parts`` sub-tasks running at once: the parent sees the mean of their fractions
    (a lock keeps reports from several threads in order)."""
    fractions = [0.0] * parts
    lock = threading.Lock()

    def part(index: int) -> Progress:
        def report(fraction: float, message: str) -> None:
            with lock:
                fractions[index] = fraction
                progress(sum(fractions) / parts, message)

        return report

    return [part(index) for index in range(parts)]
