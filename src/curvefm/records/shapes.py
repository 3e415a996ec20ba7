"""Shapes' ownership: which stored meshes exist as records, their size (charged to the first uploader's byte
quota) and who uploaded them. The meshes themselves are blobs (``meshes/<hash>.npz``, :class:`curvefm.store.Store`).

A shape used by a session (as source or target) or a collection (as template or member) cannot be deleted: the
foreign keys refuse it, and :meth:`Shapes.delete` names the users first.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from sqlalchemy import Connection, delete, func, select, update

from curvefm.errors import Conflict, NotFound, shown
from curvefm.records import models as m
from curvefm.records.common import DEFAULT_PAGE, Page, Viewer, check_page, insert_new, now
from curvefm.records.engine import Database


@dataclass(frozen=True)
class ShapeUse:
    """What uses a shape: the sessions and collections ``viewer`` may see, and how many others."""

    sessions: list[str]
    collections: list[str]
    hidden: int

    def __bool__(self) -> bool:
        return bool(self.sessions or self.collections or self.hidden)


class Shapes:
    def __init__(self, database: Database):
        self.db = database

    def add(
        self, shape: str, size: int, uploader: int | None = None, conn: Connection | None = None, name: str = ""
    ) -> bool:
        """Record a stored shape (once, with its ``name``) and note ``uploader`` (a user id) as one of its
        uploaders; its bytes are charged to its first uploader. Returns whether ``uploader`` is new to the shape."""
        with self.db.joined(conn) as tx:
            insert_new(tx, m.Shape, hash=shape, name=name[:200], bytes=size, charged_to=uploader, created_at=now())
            if name:
                tx.execute(update(m.Shape).where(m.Shape.hash == shape, m.Shape.name == "").values(name=name[:200]))
            if uploader is None:
                return False
            seq = tx.execute(select(func.count()).where(m.ShapeUploader.shape == shape)).scalar()
            if not insert_new(tx, m.ShapeUploader, shape=shape, user_id=uploader, uploaded_at=now(), seq=seq):
                return False
            tx.execute(
                update(m.Shape).where(m.Shape.hash == shape, m.Shape.charged_to.is_(None)).values(charged_to=uploader)
            )
            return True

    def exists(self, shape: str) -> bool:
        with self.db.read() as conn:
            return conn.execute(select(m.Shape.hash).where(m.Shape.hash == shape)).first() is not None

    def uploaders(self, shape: str) -> list[str]:
        """Names of the shape's uploaders who are current users, first uploader first."""
        with self.db.read() as conn:
            rows = conn.execute(
                select(m.User.name)
                .join(m.ShapeUploader, m.ShapeUploader.user_id == m.User.id)
                .where(m.ShapeUploader.shape == shape, m.User.removed_at.is_(None))
                .order_by(m.ShapeUploader.seq, m.ShapeUploader.uploaded_at)
            ).all()
        return [r.name for r in rows]

    def uploader_ids(self, shape: str) -> list[int]:
        with self.db.read() as conn:
            rows = conn.execute(
                select(m.ShapeUploader.user_id).where(m.ShapeUploader.shape == shape).order_by(m.ShapeUploader.seq)
            ).all()
        return [r.user_id for r in rows]

    def page(self, limit: int = DEFAULT_PAGE, offset: int = 0) -> Page[str]:
        """Shape ids (every user may see every shape) by name, then upload time (the newest first): ``limit`` of
        them from ``offset``, and how many there are in all, counted and sliced by the database."""
        check_page(limit, offset)
        with self.db.read() as conn:
            total = conn.execute(select(func.count()).select_from(m.Shape)).scalar() or 0
            order = (m.Shape.name, m.Shape.created_at.desc(), m.Shape.hash)
            query = select(m.Shape.hash).order_by(*order).offset(offset).limit(limit)
            items = list(conn.execute(query).scalars())
        return Page(items, total, limit, offset)

    def names(self, shapes: list[str]) -> dict[str, str]:
        """The recorded names of ``shapes`` (``""`` for a shape recorded without one)."""
        if not shapes:
            return {}
        with self.db.read() as conn:
            rows = conn.execute(select(m.Shape.hash, m.Shape.name).where(m.Shape.hash.in_(sorted(set(shapes)))))
            return {row.hash: row.name for row in rows}

    def uploaded_at(self, shape: str) -> float | None:
        """When the shape was first uploaded (None: not recorded)."""
        with self.db.read() as conn:
            return conn.execute(select(m.Shape.created_at).where(m.Shape.hash == shape)).scalar()

    def name_unnamed(self, name_of: Callable[[str], str | None]) -> int:
        """Give the shapes recorded without a name (before names were recorded, or by the command line) the name
        ``name_of(shape)`` reads from their blobs (None: the blob is gone); returns how many were named."""
        with self.db.read() as conn:
            unnamed = list(conn.execute(select(m.Shape.hash).where(m.Shape.name == "")).scalars())
        named = {shape: name for shape in unnamed if (name := name_of(shape))}
        if named:
            with self.db.write() as conn:
                for shape, name in named.items():
                    conn.execute(update(m.Shape).where(m.Shape.hash == shape).values(name=name[:200]))
        return len(named)

    def ids(self) -> list[str]:
        with self.db.read() as conn:
            return list(conn.execute(select(m.Shape.hash).order_by(m.Shape.hash)).scalars())

    def using(self, shape: str, viewer: Viewer, conn: Connection | None = None) -> ShapeUse:
        """The sessions and collections that use ``shape``, as far as ``viewer`` may see them."""

        def query(tx: Connection) -> ShapeUse:
            uses_session = (m.Session.source == shape) | (m.Session.target == shape)
            sessions = tx.execute(select(m.Session.id, m.Session.owner_id, m.Session.sharing).where(uses_session))
            member_of = select(m.Member.collection_id).where(m.Member.shape == shape)
            uses_collection = (m.Collection.template == shape) | m.Collection.id.in_(member_of)
            collections = tx.execute(
                select(m.Collection.id, m.Collection.owner_id, m.Collection.sharing).where(uses_collection)
            )
            seen_s: list[str] = []
            seen_c: list[str] = []
            hidden = 0
            for rows, seen in ((sessions, seen_s), (collections, seen_c)):
                for row in rows:
                    if viewer.admin or row.owner_id == viewer.user_id or row.sharing != "private":
                        seen.append(row.id)
                    else:
                        hidden += 1
            return ShapeUse(sorted(seen_s), sorted(seen_c), hidden)

        if conn is not None:
            return query(conn)
        with self.db.read() as fresh:
            return query(fresh)

    def delete(self, shape: str, viewer: Viewer) -> None:
        """Delete the shape's record (the caller deletes its blobs after): refused while anything uses it."""
        with self.db.write() as conn:
            if conn.execute(select(m.Shape.hash).where(m.Shape.hash == shape).with_for_update()).first() is None:
                raise NotFound(f"no shape with id '{shown(shape)}'")
            use = self.using(shape, viewer, conn)
            if use:
                named = [f"session {s}" for s in use.sessions] + [f"collection {c}" for c in use.collections]
                hidden = [f"{use.hidden} private record(s) of other users"] if use.hidden else []
                raise Conflict(
                    f"shape {shape} is used by {', '.join(named + hidden)}; delete those first (their owners or "
                    "an admin can)"
                )
            conn.execute(delete(m.Shape).where(m.Shape.hash == shape))
