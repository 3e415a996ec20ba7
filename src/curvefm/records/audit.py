"""The audit log: the operations of :class:`curvefm.access.AuditLog`, on the ``audit`` table.

An event is who (``actor``: a user name, or ``cli``; ``user_id`` when the actor is a current user) did
``action`` to ``target`` with ``detail``. Events read back as the JSON-lines log had them::

    {"time": "2026-01-02T03:04:05.678Z", "user": "alice", "action": "session.share", "target": "a1b2c3",
     "detail": {"sharing": "read"}}

Tokens and the data directory's path are redacted before an event is stored, as before.
"""

from __future__ import annotations

import json
import os
from datetime import datetime
from typing import Any

from sqlalchemy import ColumnElement, Connection, func, insert, select

from curvefm.errors import InvalidInput
from curvefm.records import models as m
from curvefm.records.common import DEFAULT_PAGE, Page, check_page, iso, now, seconds
from curvefm.records.engine import Database
from curvefm.records.users import redact_tokens


class AuditLog:
    def __init__(self, database: Database, data_dir: str | os.PathLike[str] | None = None):
        self.db = database
        roots = {str(os.path.abspath(data_dir)), os.path.realpath(data_dir)} if data_dir is not None else set()
        self._paths = sorted(roots, key=len, reverse=True)

    def record(
        self,
        user: str,
        action: str,
        target: str,
        detail: dict[str, Any] | None = None,
        conn: Connection | None = None,
        at: float | None = None,
    ) -> None:
        """Store one event: ``user`` did ``action`` (e.g. ``user.add``) to ``target`` (an id or a name)."""
        detail = json.loads(self._redact(json.dumps(detail or {})))
        with self.db.joined(conn) as tx:
            user_id = tx.execute(select(m.User.id).where(m.User.name == user, m.User.removed_at.is_(None))).scalar()
            tx.execute(
                insert(m.AuditEvent).values(
                    time=now() if at is None else at,
                    actor=self._redact(user)[:64],
                    user_id=user_id,
                    action=action[:64],
                    target=self._redact(target)[:200],
                    detail=detail,
                )
            )

    def read(
        self, limit: int = 100, since: datetime | str | None = None, user: str | None = None
    ) -> list[dict[str, Any]]:
        """The last ``limit`` events (of ``user``, at or after ``since``), oldest first; a naive ``since`` is UTC."""
        if not isinstance(limit, int) or limit < 1:
            raise InvalidInput(f"limit must be a positive integer, got {limit!r}")
        query = select(m.AuditEvent).order_by(m.AuditEvent.id.desc()).limit(limit)
        for clause in _filters(since, user):
            query = query.where(clause)
        with self.db.read() as conn:
            rows = conn.execute(query).all()
        return [_event(r) for r in reversed(rows)]

    def page(
        self, limit: int = DEFAULT_PAGE, offset: int = 0, since: datetime | str | None = None, user: str | None = None
    ) -> Page[dict[str, Any]]:
        """Events newest first, ``limit`` from ``offset``, with the total."""
        check_page(limit, offset)
        where = _filters(since, user)
        with self.db.read() as conn:
            total = conn.execute(select(func.count()).select_from(m.AuditEvent).where(*where)).scalar() or 0
            rows = conn.execute(
                select(m.AuditEvent).where(*where).order_by(m.AuditEvent.id.desc()).offset(offset).limit(limit)
            ).all()
        return Page([_event(r) for r in rows], total, limit, offset)

    def _redact(self, text: str) -> str:
        text = redact_tokens(text)
        for path in self._paths:
            text = text.replace(path, "[data]")
        return text


def _filters(since: datetime | str | None, user: str | None) -> list[ColumnElement[bool]]:
    where: list[ColumnElement[bool]] = []
    earliest = seconds(since)
    if earliest is not None:
        where.append(m.AuditEvent.time >= round(earliest, 3) - 0.0005)
    if user is not None:
        where.append(m.AuditEvent.actor == user)
    return where


def _event(row: Any) -> dict[str, Any]:
    return {"time": iso(row.time), "user": row.actor, "action": row.action, "target": row.target, "detail": row.detail}
