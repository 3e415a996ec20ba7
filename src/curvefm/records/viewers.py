"""Who has a session open (``session_viewers``: a row per open event stream), and what the API processes that
follow sessions without Redis read each tick: the sessions' revisions, the end of their last refinement and a mark of
their collection member's review comments.

A stream's row lives until ``expires_at``; its API process pushes that on at every tick while the stream lasts,
so a process that died leaves rows that expire on their own (:meth:`Viewers.purge`).
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from typing import Any

from sqlalchemy import delete, func, insert, select, update

from curvefm.errors import TooMany
from curvefm.records import models as m
from curvefm.records.engine import Database
from curvefm.records.models import ENDED_STATES
from curvefm.session.record import UnknownSession


class Viewers:
    def __init__(self, database: Database):
        self.db = database

    def open(
        self, stream_id: str, session_id: str, user_id: int, now: float, expires_at: float, limit: int, setting: str
    ) -> None:
        """Record an open stream of the user's, unless they have ``limit`` open already (:class:`TooMany` naming
        ``setting``); the count and the insert are one transaction."""
        with self.db.write() as conn:
            open_now = conn.execute(
                select(func.count())
                .select_from(m.SessionViewer)
                .where(m.SessionViewer.user_id == user_id, m.SessionViewer.expires_at > now)
            ).scalar_one()
            if open_now >= limit:
                raise TooMany(
                    f"you have {open_now} session pages following their sessions already, the most one user may "
                    f"have open at once ({setting}); close some, or wait a few seconds for closed ones to count out",
                    setting=setting,
                    retry_after=5,
                )
            if conn.execute(select(m.Session.id).where(m.Session.id == session_id)).first() is None:
                raise UnknownSession(session_id)  # deleted since the caller read it
            conn.execute(
                insert(m.SessionViewer).values(
                    id=stream_id, session_id=session_id, user_id=user_id, opened_at=now, expires_at=expires_at
                )
            )

    def heartbeat(self, stream_ids: Collection[str], now: float, expires_at: float) -> None:
        """The streams are still open until ``expires_at``; those that nobody kept open (their process ended
        without closing them) are forgotten."""
        with self.db.write() as conn:
            conn.execute(
                update(m.SessionViewer).where(m.SessionViewer.id.in_(stream_ids)).values(expires_at=expires_at)
            )
            conn.execute(delete(m.SessionViewer).where(m.SessionViewer.expires_at <= now))

    def close(self, stream_ids: Collection[str]) -> None:
        if stream_ids:
            with self.db.write() as conn:
                conn.execute(delete(m.SessionViewer).where(m.SessionViewer.id.in_(stream_ids)))

    def present(self, session_ids: Sequence[str], now: float) -> dict[str, tuple[str, ...]]:
        """Per session, the names of the users who have it open (each once, sorted)."""
        found: dict[str, set[str]] = {session_id: set() for session_id in session_ids}
        if session_ids:
            with self.db.read() as conn:
                rows = conn.execute(
                    select(m.SessionViewer.session_id, m.User.name)
                    .join(m.User, m.User.id == m.SessionViewer.user_id)
                    .where(m.SessionViewer.session_id.in_(session_ids), m.SessionViewer.expires_at > now)
                ).all()
            for session_id, name in rows:
                found[session_id].add(name)
        return {session_id: tuple(sorted(names)) for session_id, names in found.items()}

    def revisions(self, session_ids: Sequence[str]) -> dict[str, int]:
        """The stored revision of each session that still exists."""
        if not session_ids:
            return {}
        with self.db.read() as conn:
            rows = conn.execute(select(m.Session.id, m.Session.revision).where(m.Session.id.in_(session_ids)))
            return {session_id: revision for session_id, revision in rows}

    def refinements_ended(self, session_ids: Sequence[str]) -> dict[str, float]:
        """When the last refinement job of each session ended (sessions with none left out)."""
        if not session_ids:
            return {}
        with self.db.read() as conn:
            rows = conn.execute(
                select(m.Job.session_id, func.max(m.Job.ended_at))
                .where(m.Job.session_id.in_(session_ids), m.Job.kind == "refine", m.Job.state.in_(ENDED_STATES))
                .group_by(m.Job.session_id)
            )
            return {session_id: ended for session_id, ended in rows if session_id is not None and ended is not None}

    def comment_marks(self, session_ids: Sequence[str]) -> dict[str, tuple[Any, ...]]:
        """Per session of a collection member (its own or a further annotation's) whose member has review comments,
        a mark that changes with any of them: their count, the newest's creation, the resolved threads' count and
        the newest resolution (an added comment is the newest, a deletion lowers the count, a resolution is the
        newest, a reopening lowers that count)."""
        if not session_ids:
            return {}
        x, c = m.MemberAnnotation, m.ReviewComment
        owners = (
            select(m.Member.session_id, m.Member.collection_id, m.Member.id.label("member_id"))
            .where(m.Member.session_id.in_(session_ids))
            .union_all(select(x.session_id, x.collection_id, x.member_id).where(x.session_id.in_(session_ids)))
            .subquery()
        )
        of_member = (c.collection_id == owners.c.collection_id) & (c.member_id == owners.c.member_id)
        query = (
            select(
                owners.c.session_id,
                func.count(c.id),
                func.max(c.created_at),
                func.count(c.resolved_at),
                func.max(c.resolved_at),
            )
            .select_from(owners)
            .join(c, of_member)
            .group_by(owners.c.session_id)
        )
        with self.db.read() as conn:
            return {row[0]: tuple(row[1:]) for row in conn.execute(query)}
