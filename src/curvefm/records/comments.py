"""Review comments (``review_comments``): per collection member a list of threads, each comment pinned to a vertex
(a file id) of the template (``source``) or of the member's shape (``target``). A reply joins the thread of the
comment it answers and sits at its first comment's vertex; a thread is resolved (and reopened) on its first
comment. The number of comments a member holds is bounded (``max_review_comments``), counted in the transaction
that adds one.
"""

from __future__ import annotations

import secrets
from dataclasses import dataclass
from typing import Any, Literal

from sqlalchemy import ColumnElement, Connection, Row, Select, delete, func, insert, select, update

from curvefm.errors import LimitExceeded, NotFound, shown
from curvefm.records import models as m
from curvefm.records.common import now
from curvefm.records.engine import Database

Side = Literal["source", "target"]
"""Which shape of the member's session a comment is pinned to: the template or the member's shape."""


@dataclass(frozen=True)
class Comment:
    id: str
    member_id: str
    side: Side
    vertex: int
    text: str
    author: str | None
    author_id: int | None
    created_at: float
    reply_to: str | None = None
    """The first comment of the thread a reply belongs to (None: it starts a thread)."""
    resolved_by: str | None = None
    resolved_at: float | None = None


@dataclass(frozen=True)
class NewComment:
    """What a comment says and where: ``reply_to`` a comment of the thread it answers, else ``side`` and
    ``vertex``."""

    text: str
    side: Side = "target"
    vertex: int = 0
    reply_to: str | None = None


class ReviewComments:
    def __init__(self, database: Database):
        self.db = database

    def thread(self, collection_id: str, member_id: str) -> list[Comment]:
        """The member's comments, oldest first."""
        c = m.ReviewComment
        with self.db.read() as conn:
            rows = conn.execute(_comments().where(c.collection_id == collection_id, c.member_id == member_id)).all()
        return [Comment(**row._asdict()) for row in rows]

    def add(self, collection_id: str, member_id: str, new: NewComment, author_id: int, limit: int) -> Comment:
        """Add a comment by ``author_id``; 404 for an unknown ``reply_to``, 413 (``max_review_comments``) when the
        member holds ``limit`` comments already."""
        c, comment_id = m.ReviewComment, "rc" + secrets.token_hex(8)
        with self.db.write() as tx:
            count = tx.execute(
                select(func.count()).select_from(c).where(c.collection_id == collection_id, c.member_id == member_id)
            ).scalar_one()
            if count >= limit:
                raise LimitExceeded("max_review_comments", limit, f"{count + 1} comments on member {member_id}")
            side, vertex, root = new.side, new.vertex, None
            if new.reply_to is not None:
                first = _first_of_thread(tx, collection_id, member_id, new.reply_to)
                side, vertex, root = first.side, first.vertex, first.id
            values = {"side": side, "vertex": vertex, "text": new.text, "author_id": author_id, "reply_to": root}
            tx.execute(
                insert(c).values(
                    id=comment_id, collection_id=collection_id, member_id=member_id, created_at=now(), **values
                )
            )
        return self.get(collection_id, member_id, comment_id)

    def get(self, collection_id: str, member_id: str, comment_id: str) -> Comment:
        with self.db.read() as conn:
            row = conn.execute(_comments().where(*_named(collection_id, member_id, comment_id))).first()
        if row is None:
            raise _unknown(member_id, comment_id)
        return Comment(**row._asdict())

    def resolve(self, collection_id: str, member_id: str, comment_id: str, by: int, resolved: bool) -> Comment:
        """Resolve (or reopen) the thread of the comment; returns the thread's first comment."""
        with self.db.write() as tx:
            first = _first_of_thread(tx, collection_id, member_id, comment_id)
            change = (
                {"resolved_by": by, "resolved_at": now()} if resolved else {"resolved_by": None, "resolved_at": None}
            )
            tx.execute(update(m.ReviewComment).where(m.ReviewComment.id == first.id).values(change))
        return self.get(collection_id, member_id, first.id)

    def delete(self, collection_id: str, member_id: str, comment_id: str) -> None:
        """Delete the comment (a thread's first comment: with its replies)."""
        with self.db.write() as tx:
            if tx.execute(delete(m.ReviewComment).where(*_named(collection_id, member_id, comment_id))).rowcount == 0:
                raise _unknown(member_id, comment_id)

    def sessions(self, collection_id: str, member_id: str) -> dict[str, int]:
        """The sessions that show the member's comments, with their revisions: its own and its further
        annotations'."""
        x = m.MemberAnnotation
        own = select(m.Member.session_id).where(m.Member.collection_id == collection_id, m.Member.id == member_id)
        further = select(x.session_id).where(x.collection_id == collection_id, x.member_id == member_id)
        with self.db.read() as conn:
            rows = conn.execute(
                select(m.Session.id, m.Session.revision).where(m.Session.id.in_(own.union_all(further)))
            ).all()
        return {session_id: revision for session_id, revision in rows}

    def annotates(self, collection_id: str, member_id: str, user_id: int) -> bool:
        """Whether the user makes a further annotation of the member (double annotation)."""
        x = m.MemberAnnotation
        mine = (x.collection_id == collection_id, x.member_id == member_id, x.user_id == user_id)
        with self.db.read() as conn:
            return conn.execute(select(x.session_id).where(*mine)).first() is not None


def _comments() -> Select[Any]:
    c = m.ReviewComment
    author, resolver = m.User.__table__.alias("author"), m.User.__table__.alias("resolver")
    return (
        select(
            c.id,
            c.member_id,
            c.side,
            c.vertex,
            c.text,
            author.c.name.label("author"),
            c.author_id,
            c.created_at,
            c.reply_to,
            resolver.c.name.label("resolved_by"),
            c.resolved_at,
        )
        .outerjoin(author, author.c.id == c.author_id)
        .outerjoin(resolver, resolver.c.id == c.resolved_by)
        .order_by(c.created_at, c.id)
    )


def _first_of_thread(tx: Connection, collection_id: str, member_id: str, comment_id: str) -> Row[str, str, int]:
    """The first comment of the comment's thread (itself when it starts one): its id, side and vertex."""
    c = m.ReviewComment
    row = tx.execute(select(c.id, c.reply_to).where(*_named(collection_id, member_id, comment_id))).first()
    if row is None:
        raise _unknown(member_id, comment_id)
    return tx.execute(select(c.id, c.side, c.vertex).where(c.id == (row.reply_to or row.id))).one()


def _named(collection_id: str, member_id: str, comment_id: str) -> tuple[ColumnElement[bool], ...]:
    c = m.ReviewComment
    return (c.collection_id == collection_id, c.member_id == member_id, c.id == comment_id)


def _unknown(member_id: str, comment_id: str) -> NotFound:
    return NotFound(f"no comment '{shown(comment_id)}' on member {member_id}")
