"""Progress reporting shared by long computations, jobs and the CLI."""

from __future__ import annotations

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
