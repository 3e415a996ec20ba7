"""Quotas as queries: what a user has is counted where it is recorded, never kept in a ledger of its own.

* stored bytes: ``SUM(shapes.bytes)`` of the shapes charged to the user (their first uploader) plus
  ``SUM(jobs.result_bytes)`` of the user's jobs (an expired job's row is gone, so are its bytes) plus
  ``SUM(sessions.bytes)`` of the sessions the user owns (what their curves store);
* sessions: ``COUNT(sessions)`` the user owns, collections' member sessions included;
* concurrent jobs: ``COUNT(jobs)`` of the user's queued or started.

:meth:`Quotas.admit` checks in the transaction that then makes the thing (the block receives its connection):
the user's row is locked first (``SELECT ... FOR UPDATE``; SQLite's write transaction holds the whole database),
so a user's parallel requests cannot pass one check together, and a block that fails undoes what it charged.
Admins are exempt (what they make is still theirs).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Literal

from sqlalchemy import Connection, func, select

from curvefm.errors import ResourceLimit, TooMany
from curvefm.records import models as m
from curvefm.records.engine import Database
from curvefm.records.users import User

Charged = Literal["shapes", "sessions", "jobs"]


@dataclass(frozen=True)
class Limits:
    """The quotas (0: no limit) and the names of their settings, for the errors."""

    bytes: int = 0
    sessions: int = 0
    jobs: int = 0
    bytes_setting: str = "CURVEFM_QUOTA_BYTES"
    sessions_setting: str = "CURVEFM_QUOTA_SESSIONS"
    jobs_setting: str = "CURVEFM_QUOTA_JOBS"


@dataclass(frozen=True)
class UsageCounts:
    shape_bytes: int
    result_bytes: int
    sessions: int
    active_jobs: int
    session_bytes: int = 0

    @property
    def bytes(self) -> int:
        return self.shape_bytes + self.result_bytes + self.session_bytes


class Quotas:
    def __init__(self, database: Database, limits: Limits):
        self.db, self.limits = database, limits

    def usage(self, user_id: int, conn: Connection | None = None) -> UsageCounts:
        if conn is not None:
            return counts(conn, user_id)
        with self.db.read() as fresh:
            return counts(fresh, user_id)

    @contextmanager
    def admit(self, user: User | None, kind: Charged, incoming_bytes: int = 0, count: int = 1) -> Iterator[Connection]:
        """A write transaction in which the block makes ``count`` things of ``kind`` (one, but for a collection's
        member sessions), after checking the user's quotas:

        * ``shapes``: 413 when ``incoming_bytes`` would pass the byte quota;
        * ``sessions``: 429 when ``count`` more would pass the sessions quota;
        * ``jobs``: 429 at the concurrent-jobs quota, 413 when the user's bytes are at their quota already.

        Without a user (made by the server) nothing is checked."""
        with self.db.write() as conn:
            if user is not None and not user.admin:
                conn.execute(select(m.User.id).where(m.User.id == user.id).with_for_update()).first()
                used = counts(conn, user.id)
                if kind == "shapes":
                    self._check_bytes(used, incoming_bytes)
                elif kind == "sessions":
                    limit, setting = self.limits.sessions, self.limits.sessions_setting
                    _check_count(user, used.sessions + count - 1, limit, setting, SESSIONS)
                elif kind == "jobs":
                    _check_count(user, used.active_jobs, self.limits.jobs, self.limits.jobs_setting, JOBS)
                    self._check_bytes(used, 0)
            yield conn

    def _check_bytes(self, used: UsageCounts, incoming: int) -> None:
        limit = self.limits.bytes
        if limit and (used.bytes + incoming > limit or used.bytes >= limit):
            adds = f", this would add {incoming}" if incoming else ""
            raise ResourceLimit(
                f"your stored data is {used.bytes} bytes{adds}, and the quota is {limit} bytes "
                f"({self.limits.bytes_setting}; {used.session_bytes} of them your sessions' curves); results "
                "expire after a while, or delete results, sessions and shapes you uploaded, or ask an admin to raise "
                "the limit",
                setting=self.limits.bytes_setting,
            )


SESSIONS = ("sessions", "delete one first or ask an admin to raise the limit")
JOBS = ("jobs queued or running", "wait for one to end or cancel one")


def _check_count(user: User, count: int, limit: int, setting: str, described: tuple[str, str]) -> None:
    what, remedy = described
    if limit and count >= limit:
        raise TooMany(
            f"{user.name} has {count} {what}, the most allowed ({setting}={limit}); {remedy}", setting=setting
        )


def counts(conn: Connection, user_id: int) -> UsageCounts:
    shape_bytes = conn.execute(select(func.coalesce(func.sum(m.Shape.bytes), 0)).where(m.Shape.charged_to == user_id))
    result_bytes = conn.execute(select(func.coalesce(func.sum(m.Job.result_bytes), 0)).where(m.Job.owner_id == user_id))
    sessions = conn.execute(
        select(func.count(), func.coalesce(func.sum(m.Session.bytes), 0)).where(m.Session.owner_id == user_id)
    ).one()
    active = conn.execute(
        select(func.count()).select_from(m.Job).where(m.Job.owner_id == user_id, m.Job.state.in_(m.ACTIVE_STATES))
    )
    return UsageCounts(
        int(shape_bytes.scalar() or 0),
        int(result_bytes.scalar() or 0),
        int(sessions[0] or 0),
        int(active.scalar() or 0),
        int(sessions[1] or 0),
    )
