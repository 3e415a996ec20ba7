"""Bounds on the work one request may ask of a session; each is configurable and named in its error.

Waypoints bound the tracing (one tracer run per pair of consecutive waypoints: 2,000 waypoints took 2.6 s on a
6,890-vertex shape), path vertices bound what a curve stores and the resampling, curves bound a session's record
(it is read and written whole on every edit), and ``k`` bounds the basis a request may have computed and the
``k x k`` systems of every edit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from curvefm.errors import LimitExceeded


@dataclass(frozen=True)
class SessionLimits:
    max_waypoints: int = field(default=100, metadata={"help": "waypoints per side of a curve"})
    max_path_vertices: int = field(default=20_000, metadata={"help": "vertices per curve path, traced or explicit"})
    max_curves: int = field(default=200, metadata={"help": "curves per session"})
    max_k: int = field(default=500, metadata={"help": "basis functions a session or basis request may ask for"})
    max_members: int = field(default=200, metadata={"help": "members per collection (each is a session)"})

    def check(self, name: str, value: int, what: str) -> None:
        """Raise :class:`LimitExceeded` if ``value`` (described by ``what``, e.g. "2000 waypoints on the source")
        exceeds the limit ``name``."""
        limit = getattr(self, name)
        if value > limit:
            raise LimitExceeded(name, limit, what)
