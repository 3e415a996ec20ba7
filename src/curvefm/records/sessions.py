"""Session records on ``sessions`` and ``curves`` (the service's and the command line's session store).

A write is one transaction that updates the session's row only if its revision is still the one the edit
started from (``UPDATE ... WHERE id = :id AND revision = :read``): two writers that read the same revision
cannot both win, and the loser gets :class:`StaleRevision` instead of overwriting the other's edit. A write given
the record it started from (``base``) stores only the curves that changed (one curve edit writes one curve).

Lists are pages filtered in SQL: by who may see them (owner, sharing, admin), owner, shape, a text in the name or
the shapes' names, collection membership; newest change first.
"""

from __future__ import annotations

import builtins
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial
from typing import Any

from sqlalchemy import ColumnElement, Connection, ScalarSelect, bindparam, delete, func, insert, or_, select, update
from sqlalchemy.exc import IntegrityError

from curvefm.errors import Conflict, InvalidInput, LimitExceeded, NotFound, StaleRevision, shown
from curvefm.records import models as m
from curvefm.records.common import (
    DEFAULT_PAGE,
    Page,
    Viewer,
    after_cursor,
    check_page,
    encode_cursor,
    insert_new,
    now,
    path_array,
    path_bytes,
    visible,
    well_formed,
)
from curvefm.records.engine import Database, shared_database
from curvefm.records.users import owner_id, owner_name
from curvefm.records.webhooks import DEFAULT_LOG_SIZE, announce_member_removed
from curvefm.session.record import CurveRecord, SessionRecord, UnknownSession
from curvefm.store import Store

SCALARS = (
    "name",
    "sharing",
    "source",
    "target",
    "k",
    "alpha",
    "samples",
    "energy",
    "tracer",
    "basis_plugin",
    "basis_params",
    "next_curve",
)
"""What a write may change besides the curves (the id, owner and creation time stay)."""
StoredShape = Callable[[str], "int | None"]
"""A shape id -> the size of its stored mesh blob (None: no such blob). A session naming a shape whose blob is
stored but which has no record yet (a mesh stored by the command line) records it, charged to nobody."""
OwnerIds = Callable[[str], "int | None"]
"""A user name (``""``: none) -> its user id."""
MAX_CURVE_BYTES = 2 * 4 * 20_000
"""The most one curve's two paths take (two sides of ``max_path_vertices`` int32 ids)."""
MAX_SESSION_BYTES = 4 * 1024 * 1024
"""The default cap on what a session's curves store (:func:`stored_bytes`; the service's
``CURVEFM_MAX_SESSION_BYTES``): a few hundred long curves, far more than hand-placed ones take."""
NOT_READ = ("owner_id", "bytes")
"""Columns that a :class:`SessionRecord` has not (the owner is read by name; the size is the quota's)."""


@dataclass(frozen=True)
class SessionSummary:
    """A session as a list shows it: everything but the curves, and how many it has."""

    id: str
    name: str
    owner: str
    owner_id: int | None
    sharing: str
    source: str
    target: str
    k: int
    alpha: float
    samples: int
    energy: str
    tracer: str
    basis_plugin: str
    revision: int
    created_at: float
    updated_at: float
    n_curves: int
    source_name: str = ""
    target_name: str = ""
    collection: str | None = None
    """The collection the session is a member session of (None: a session of its own)."""
    member: str | None = None


class Sessions:
    """A write of more than ``max_curves`` curves, of a curve of more than ``max_curve_bytes``, or of a session
    whose curves store more than ``max_session_bytes`` is refused. Each session's row keeps that size (``bytes``),
    which counts in its owner's byte quota."""

    def __init__(
        self,
        database: Database,
        max_curves: int = 200,
        max_curve_bytes: int = MAX_CURVE_BYTES,
        lock_timeout_s: float = 30.0,
        stored_shape: StoredShape | None = None,
        max_session_bytes: int = MAX_SESSION_BYTES,
        webhook_log_size: int = DEFAULT_LOG_SIZE,
    ):
        self.db, self.max_curves, self.max_curve_bytes = database, max_curves, max_curve_bytes
        self.max_session_bytes, self.webhook_log_size = max_session_bytes, webhook_log_size
        self.lock_timeout_s = lock_timeout_s
        self.stored_shape = stored_shape

    # -- reading --------------------------------------------------------------------------------------------
    def exists(self, session_id: str) -> bool:
        if not well_formed(session_id):
            return False
        with self.db.read() as conn:
            return conn.execute(select(m.Session.id).where(m.Session.id == session_id)).first() is not None

    def read(self, session_id: str, conn: Connection | None = None) -> SessionRecord:
        if conn is not None:
            return self._read(conn, session_id)
        with self.db.read() as fresh:
            return self._read(fresh, session_id)

    def read_changed(self, session_id: str, revision: int) -> SessionRecord | None:
        """The stored record if its revision is not ``revision``, else None (then only the revision is read)."""
        with self.db.read() as conn:
            stored = self._revision(conn, session_id)
            return None if stored == revision else self._read(conn, session_id)

    def owner_of(self, session_id: str) -> int | None:
        """The owner's user id (None: made before users existed)."""
        with self.db.read() as conn:
            row = conn.execute(select(m.Session.owner_id).where(m.Session.id == session_id)).first()
        if row is None:
            raise UnknownSession(session_id)
        return row.owner_id

    def page(
        self,
        viewer: Viewer,
        limit: int = DEFAULT_PAGE,
        offset: int = 0,
        cursor: str | None = None,
        owner: int | None = None,
        shape: str | None = None,
        query: str | None = None,
        in_collection: bool | None = None,
    ) -> Page[SessionSummary]:
        """The sessions ``viewer`` may see (of ``owner``, using ``shape``, whose name or shape names contain
        ``query`` whatever the case, of a collection or not as ``in_collection`` says: a member's, or a further
        annotation of one), newest change first: ``limit`` of them from ``offset``, or after ``cursor`` (the
        ``next_cursor`` of the page before)."""
        check_page(limit, offset)
        where = [visible(m.Session.owner_id, m.Session.sharing, viewer)]
        if owner is not None:
            where.append(m.Session.owner_id == owner)
        if shape is not None:
            where.append((m.Session.source == shape) | (m.Session.target == shape))
        if query:
            named = select(m.Shape.hash).where(_contains(m.Shape.name, query))
            in_name = _contains(m.Session.name, query)
            where.append(or_(in_name, m.Session.source.in_(named), m.Session.target.in_(named)))
        if in_collection is not None:
            members = select(m.Member.session_id).union_all(select(m.MemberAnnotation.session_id))
            where.append(m.Session.id.in_(members) if in_collection else m.Session.id.not_in(members))
        # per row of the page, subqueries (not joins): the count and the page's sort stay on the sessions table
        n_curves = select(func.count()).where(m.Curve.session_id == m.Session.id).correlate(m.Session).scalar_subquery()
        columns = [c for c in m.Session.__table__.c if c.name not in ("basis_params", "next_curve", *NOT_READ)]
        member = m.Member.session_id == m.Session.id
        query_rows = (
            select(
                *columns,
                m.Session.owner_id,
                owner_name(),
                n_curves.label("n_curves"),
                _shape_name(m.Session.source).label("source_name"),
                _shape_name(m.Session.target).label("target_name"),
                select(m.Member.collection_id).where(member).correlate(m.Session).scalar_subquery().label("collection"),
                select(m.Member.id).where(member).correlate(m.Session).scalar_subquery().label("member"),
            )
            .outerjoin(m.User, m.User.id == m.Session.owner_id)
            .where(*where)
            .order_by(m.Session.updated_at.desc(), m.Session.id.desc())
        )
        with self.db.read() as conn:
            total = conn.execute(select(func.count()).select_from(m.Session).where(*where)).scalar() or 0
            if cursor:
                query_rows = query_rows.where(after_cursor(m.Session.updated_at, m.Session.id, cursor))
            else:
                query_rows = query_rows.offset(offset)
            rows = conn.execute(query_rows.limit(limit + 1)).all()
        items = [SessionSummary(**row._asdict()) for row in rows[:limit]]
        more = len(rows) > limit
        next_cursor = encode_cursor(items[-1].updated_at, items[-1].id) if more and items else None
        return Page(items, total, limit, 0 if cursor else offset, next_cursor)

    def ids(self) -> list[str]:
        with self.db.read() as conn:
            return list(conn.execute(select(m.Session.id).order_by(m.Session.id)).scalars())

    # -- what the file store offered, for a swap ------------------------------------------------------------
    @contextmanager
    def locked(self, record_id: str, new: bool = False) -> Iterator[None]:
        """No lock is needed (a write checks the revision it started from); raises for an unknown record as the
        file store's lock did, unless it is ``new``."""
        if not new and not self.exists(record_id):
            raise UnknownSession(record_id)
        yield

    def list(self) -> builtins.list[SessionRecord]:
        """Every record, the most recently changed first. Reads them all: lists for people use :meth:`page`."""
        with self.db.read() as conn:
            ids = conn.execute(
                select(m.Session.id).order_by(m.Session.updated_at.desc(), m.Session.id.desc())
            ).scalars()
            return [self._read(conn, record_id) for record_id in list(ids)]

    # -- changing -------------------------------------------------------------------------------------------
    def create(self, record: SessionRecord, conn: Connection | None = None, owner: OwnerIds | None = None) -> None:
        """Store a new record as it is (owner by name, ``""``: none); an id in use is a conflict, a shape that
        is not stored is not found. ``owner`` finds the owner's user id from the name (default: the current
        user of that name)."""
        if not well_formed(record.id):
            raise InvalidInput(f"a session id is 1-64 letters, digits, '-' or '_', got '{shown(record.id)}'")
        size = self._check_size(record)
        try:
            with self.db.joined(conn) as tx:
                if tx.execute(select(m.Session.id).where(m.Session.id == record.id)).first() is not None:
                    raise Conflict(f"session '{record.id}' already exists")
                _require_shapes(tx, self.stored_shape, record.source, record.target)
                values = {name: getattr(record, name) for name in SCALARS}
                tx.execute(
                    insert(m.Session).values(
                        id=record.id,
                        owner_id=(owner or partial(owner_id, tx))(record.owner),
                        revision=record.revision,
                        created_at=record.created_at,
                        updated_at=record.updated_at,
                        bytes=size,
                        **values,
                    )
                )
                _insert_curves(tx, record.id, list(enumerate(record.curves)))
        except IntegrityError as exc:
            raise Conflict(f"session '{record.id}' cannot be stored: {_reason(exc)}") from None

    def write(
        self, record: SessionRecord, base: SessionRecord | None = None, conn: Connection | None = None
    ) -> SessionRecord:
        """Store ``record`` as the next revision after ``record.revision`` (:class:`StaleRevision` if the stored
        one moved on); returns what was stored. ``base``: the stored record the edit started from, when the
        caller has it (only the curves that differ from it are written)."""
        size = self._check_size(record)
        written = record.model_copy(update={"revision": record.revision + 1, "updated_at": now()})
        with self.db.joined(conn) as tx:
            values = {name: getattr(record, name) for name in SCALARS}
            changes = {"revision": written.revision, "updated_at": written.updated_at, "bytes": size, **values}
            done = tx.execute(_UPDATE_FROM, {"at_id": record.id, "at_revision": record.revision, **changes})
            if done.rowcount != 1:
                stored = self._revision(tx, record.id)
                if stored is None:
                    raise UnknownSession(record.id)
                raise StaleRevision("session", record.id, record.revision, stored)
            if base is not None and base.id == record.id and base.revision == record.revision:
                _write_changed_curves(tx, record.id, base.curves, record.curves)
            else:
                tx.execute(delete(m.Curve).where(m.Curve.session_id == record.id))
                _insert_curves(tx, record.id, list(enumerate(record.curves)))
        return written

    def delete(self, session_id: str, conn: Connection | None = None) -> builtins.list[str]:
        """Delete the session with its curves (and its collection membership, announced to the collection's
        webhooks in the same transaction); returns the ids of the refinement jobs run from it (their results are the
        caller's to delete; their records stay)."""
        with self.db.joined(conn) as tx:
            jobs = self._jobs(tx, session_id)
            # a collection losing the member moves to its next revision: a write from a copy read before fails
            member_of = select(m.Member.collection_id).where(m.Member.session_id == session_id)
            tx.execute(
                update(m.Collection)
                .where(m.Collection.id.in_(member_of))
                .values(revision=m.Collection.revision + 1, updated_at=now())
            )
            announce_member_removed(tx, session_id, self.webhook_log_size)
            if tx.execute(delete(m.Session).where(m.Session.id == session_id)).rowcount != 1:
                raise UnknownSession(session_id)
        return jobs

    remove = delete

    def add_job(self, session_id: str, job_id: str, conn: Connection | None = None) -> None:
        """Note that the job (its record exists) was run from the session."""
        with self.db.joined(conn) as tx:
            if self._revision(tx, session_id) is None:
                raise UnknownSession(session_id)
            done = tx.execute(update(m.Job).where(m.Job.id == job_id).values(session_id=session_id))
            if done.rowcount != 1:
                raise NotFound(f"no job with id '{shown(job_id)}'")

    def jobs(self, session_id: str) -> builtins.list[str]:
        with self.db.read() as conn:
            return self._jobs(conn, session_id)

    # -- helpers ------------------------------------------------------------------------------------------
    def _check_size(self, record: SessionRecord) -> int:
        """What the record's curves store (:func:`stored_bytes`), once it is within the limits."""
        if len(record.curves) > self.max_curves:
            raise LimitExceeded("max_curves", self.max_curves, f"{len(record.curves)} curves in session {record.id}")
        for curve in record.curves:
            size = 4 * (len(curve.path_source) + len(curve.path_target))
            if size > self.max_curve_bytes:
                raise LimitExceeded(
                    "max_path_vertices", self.max_curve_bytes // 8, f"{size // 4} path vertices in curve {curve.id}"
                )
        size = stored_bytes(record)
        if size > self.max_session_bytes:
            what = f"session {record.id}'s curves would store {size} bytes"
            raise LimitExceeded("max_session_bytes", self.max_session_bytes, what, " bytes")
        return size

    @staticmethod
    def _jobs(conn: Connection, session_id: str) -> builtins.list[str]:
        rows = conn.execute(select(m.Job.id).where(m.Job.session_id == session_id).order_by(m.Job.created_at, m.Job.id))
        return list(rows.scalars())

    @staticmethod
    def _revision(conn: Connection, session_id: str) -> int | None:
        return conn.execute(_REVISION, {"session_id": session_id}).scalar()

    @staticmethod
    def _read(conn: Connection, session_id: str) -> SessionRecord:
        if not well_formed(session_id):
            raise UnknownSession(session_id)
        row = conn.execute(_ROW, {"session_id": session_id}).first()
        if row is None:
            raise UnknownSession(session_id)
        curves = conn.execute(_CURVES, {"session_id": session_id}).all()
        return SessionRecord.model_validate(
            {
                **row._asdict(),
                "curves": [
                    CurveRecord(
                        id=c.id,
                        spec=c.spec,
                        tracer=c.tracer,
                        path_source=path_array(c.path_source),
                        path_target=path_array(c.path_target),
                    )
                    for c in curves
                ],
            }
        )


# The statements of every edit, built once: SQLAlchemy keys its cache of compiled statements by a traversal of the
# statement, which costs a new statement object more than running it does (a session's read 2-3x).
_ROW = (
    select(*(c for c in m.Session.__table__.c if c.name not in NOT_READ), owner_name())
    .outerjoin(m.User, m.User.id == m.Session.owner_id)
    .where(m.Session.id == bindparam("session_id"))
)
_CURVES = (
    select(m.Curve.id, m.Curve.spec, m.Curve.tracer, m.Curve.path_source, m.Curve.path_target)
    .where(m.Curve.session_id == bindparam("session_id"))
    .order_by(m.Curve.position)
)
_REVISION = select(m.Session.revision).where(m.Session.id == bindparam("session_id"))
_UPDATE_FROM = update(m.Session).where(
    m.Session.id == bindparam("at_id"), m.Session.revision == bindparam("at_revision")
)
"""The session's row if still at the revision read (its new values are the execution's other parameters)."""
_DELETE_CURVE = delete(m.Curve).where(  # one id a row of parameters: an expanding IN is rendered anew each time
    m.Curve.session_id == bindparam("in_session"), m.Curve.id == bindparam("curve")
)
_MOVE_CURVE = (
    update(m.Curve)
    .where(m.Curve.session_id == bindparam("in_session"), m.Curve.id == bindparam("curve"))
    .values(position=bindparam("to"))
)
_INSERT_CURVES = insert(m.Curve)


def sessions_of(store: Store, url: str | None = None, **options: Any) -> Sessions:
    """The session records of a data directory's database (``url``, else ``$CURVEFM_DATABASE_URL``, else its SQLite
    file), recording the store's meshes as shapes when a session first names them; ``options`` as
    :class:`Sessions`'."""
    return Sessions(shared_database(store.root, url), stored_shape=partial(blob_bytes, store), **options)


def stored_bytes(record: SessionRecord) -> int:
    """What a session's curves store, counted as 4 bytes a vertex id: their traced paths and the waypoints or
    paths they were given."""
    ids = (len(c.path_source) + len(c.path_target) + len(c.spec.source) + len(c.spec.target) for c in record.curves)
    return 4 * sum(ids)


def blob_bytes(store: Store, mesh_id: str) -> int | None:
    """The size of a stored mesh's blob (None: not stored)."""
    if not store.has_mesh(mesh_id):  # (checks the id's form too)
        return None
    try:
        return store.mesh_path(mesh_id).stat().st_size
    except FileNotFoundError:  # deleted meanwhile
        return None


def _curve_row(session_id: str, position: int, curve: CurveRecord) -> dict[str, Any]:
    return {
        "session_id": session_id,
        "id": curve.id,
        "position": position,
        "spec": curve.spec.model_dump(mode="json"),
        "tracer": curve.tracer,
        "path_source": path_bytes(curve.path_source),
        "path_target": path_bytes(curve.path_target),
    }


def _insert_curves(conn: Connection, session_id: str, curves: list[tuple[int, CurveRecord]]) -> None:
    if curves:
        conn.execute(_INSERT_CURVES, [_curve_row(session_id, position, curve) for position, curve in curves])


def _write_changed_curves(
    conn: Connection, session_id: str, before: list[CurveRecord], after: list[CurveRecord]
) -> None:
    """Write what differs between the stored curves ``before`` and ``after``: removed, added, changed or moved."""
    old = {curve.id: (position, curve) for position, curve in enumerate(before)}
    new_ids = {curve.id for curve in after}
    gone = [curve_id for curve_id in old if curve_id not in new_ids]
    added, moved = [], []
    for position, curve in enumerate(after):
        if curve.id not in old:
            added.append((position, curve))
            continue
        old_position, old_curve = old[curve.id]
        if curve is not old_curve and curve != old_curve:
            gone.append(curve.id)
            added.append((position, curve))
        elif position != old_position:
            moved.append({"in_session": session_id, "curve": curve.id, "to": position})
    if gone:
        conn.execute(_DELETE_CURVE, [{"in_session": session_id, "curve": curve_id} for curve_id in gone])
    if moved:
        conn.execute(_MOVE_CURVE, moved)
    _insert_curves(conn, session_id, added)


def _require_shapes(conn: Connection, stored: StoredShape | None, *shapes: str) -> None:
    found = set(conn.execute(select(m.Shape.hash).where(m.Shape.hash.in_(shapes))).scalars())
    for shape in shapes:
        if shape in found:
            continue
        size = stored(shape) if stored is not None else None
        if size is None:
            raise NotFound(f"no shape with id '{shown(shape)}'")
        insert_new(conn, m.Shape, hash=shape, bytes=size, charged_to=None, created_at=now())


def _shape_name(shape: Any) -> ScalarSelect[str]:
    """The name of the shape ``shape`` (a session's column) names, as a subquery of a session's row."""
    return select(m.Shape.name).where(m.Shape.hash == shape).correlate(m.Session).scalar_subquery()


def _contains(column: Any, text: str) -> ColumnElement[bool]:
    """``column`` contains ``text``, whatever the case (``%`` and ``_`` in ``text`` are themselves)."""
    return func.lower(column).contains(text.lower(), autoescape=True)


def _reason(exc: IntegrityError) -> str:
    return " ".join(str(exc.orig).split())[:200]
