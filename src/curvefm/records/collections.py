"""Collection records (the collections' store of the service and the command line), on ``collections`` and its
children ``template_curves``, ``collection_members`` and ``collection_runs`` / ``run_members``.

A write checks the revision as a session's does and replaces the children (a collection has at most a few hundred
members and is written rarely). Members point at their sessions: a member's session is created in the same
transaction as the member (:meth:`Collections.add_members`), deleting the collection deletes its member sessions
(:meth:`Collections.delete` returns their jobs, whose results the caller deletes), and deleting a member's
session alone removes the member (the collection stays readable). A run remembers each member's job id; when
the job's record expires, ``run_members.job_id`` becomes NULL and :meth:`Collections.expired_jobs` names it.
Roles, assignments, review states (``member_reviews``), further annotations (``member_annotations``, each with a
session of its own that goes with its member) and check members' ground truths (``member_truths``) are rows beside
them.
"""

from __future__ import annotations

import builtins
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial
from typing import Literal

import numpy as np
from sqlalchemy import (
    ColumnElement,
    Connection,
    Select,
    and_,
    bindparam,
    delete,
    exists,
    false,
    func,
    insert,
    literal,
    or_,
    select,
    true,
    union_all,
    update,
)
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import aliased

from curvefm.collection.record import CollectionRecord, Member, Run, RunMember, TemplateCurve, UnknownCollection
from curvefm.errors import Conflict, InvalidInput, NotFound, StaleRevision, shown
from curvefm.records import models as m
from curvefm.records.common import (
    DEFAULT_PAGE,
    Page,
    Viewer,
    after_cursor,
    check_page,
    encode_cursor,
    now,
    path_array,
    path_bytes,
    visible,
    well_formed,
)
from curvefm.records.engine import Database
from curvefm.records.sessions import OwnerIds, Sessions, _require_shapes
from curvefm.records.users import owner_id, owner_name
from curvefm.session.record import SessionRecord

SCALARS = (
    "name",
    "sharing",
    "template",
    "k",
    "alpha",
    "samples",
    "energy",
    "tracer",
    "basis_plugin",
    "basis_params",
    "next_member",
    "next_run",
)


ROLES = ("owner", "manager", "annotator", "reviewer", "viewer")
"""The roles a user may hold in a collection, the most powerful first."""


@dataclass(frozen=True)
class Standing:
    """Where a viewer stands in a collection: whether they made it, its lab-wide sharing and the role granted
    to them (None: none)."""

    collection_id: str
    creator: bool
    sharing: str
    role: str | None
    assigning: bool = False
    """Whether any member of the collection is assigned (then annotators answer only their own)."""
    assignee: int | None = None
    """The stable id of the user the member asked about is assigned to."""


@dataclass(frozen=True)
class Work:
    """A member assigned to a user, or one they annotate once more: its collection, the session and shape."""

    collection_id: str
    collection_name: str
    member_id: str
    session_id: str
    shape: str
    further: bool = False
    """A further annotation of the member (double annotation), in a session of its own."""


ReviewState = Literal["open", "submitted", "changes_requested", "accepted"]
"""Where a member stands in review (``open``: never submitted; it holds no row)."""
LOCKED_STATES = ("submitted", "accepted")
"""The review states in which a member's curves may not change (a reviewer sends it back to reopen it)."""
_LOCKED_MEMBER = (
    select(m.Member.collection_id, m.Member.id, m.MemberReview.state)
    .join(
        m.MemberReview,
        (m.MemberReview.collection_id == m.Member.collection_id) & (m.MemberReview.member_id == m.Member.id),
    )
    .where(
        m.Member.session_id == bindparam("session_id"),
        m.MemberReview.state.in_([literal(state) for state in LOCKED_STATES]),
    )
)
"""Asked before every curve edit: built once (SQLAlchemy's cache key of a new statement costs more than the query),
with one parameter per state: a plain ``in_(LOCKED_STATES)`` is an expanding parameter, rendered anew on every
execution (half of this query's time)."""


@dataclass(frozen=True)
class Review:
    """A member's review state, who submitted it and when, who reviewed it last and when, and their comment."""

    member_id: str
    state: ReviewState = "open"
    submitted_by: str | None = None
    submitted_at: float | None = None
    reviewed_by: str | None = None
    reviewed_at: float | None = None
    comment: str = ""


@dataclass(frozen=True)
class Annotation:
    """An annotator's own session on a member: the member's session (its assignee's) or a further annotation."""

    member_id: str
    user_id: int | None
    user: str | None
    session_id: str
    further: bool
    """A further annotation (double annotation), not the member's own session."""


@dataclass(frozen=True)
class Truth:
    """A check member's ground truth: ``truth[v]`` is the member vertex (file id, -1: unknown) of template vertex
    ``v`` (file id); who gave it and when."""

    member_id: str
    truth: np.ndarray
    set_by: str | None
    set_at: float


@dataclass(frozen=True)
class Grant:
    """A role held in a collection: by whom (name and stable id), granted by whom and when."""

    user: str
    user_id: int
    role: str
    granted_by: str | None
    granted_at: float


@dataclass(frozen=True)
class CollectionSummary:
    id: str
    name: str
    owner: str
    owner_id: int | None
    sharing: str
    template: str
    k: int
    revision: int
    created_at: float
    updated_at: float
    n_curves: int
    n_members: int


class Collections:
    def __init__(self, database: Database, sessions: Sessions | None = None):
        self.db = database
        self.sessions = sessions or Sessions(database)

    # -- reading --------------------------------------------------------------------------------------------
    def exists(self, collection_id: str) -> bool:
        if not well_formed(collection_id):
            return False
        with self.db.read() as conn:
            return _revision(conn, collection_id) is not None

    def read(self, collection_id: str, conn: Connection | None = None) -> CollectionRecord:
        if conn is not None:
            return _read(conn, collection_id)
        with self.db.read() as fresh:
            return _read(fresh, collection_id)

    def page(
        self,
        viewer: Viewer,
        limit: int = DEFAULT_PAGE,
        offset: int = 0,
        cursor: str | None = None,
        owner: int | None = None,
    ) -> Page[CollectionSummary]:
        check_page(limit, offset)
        c = m.Collection
        where = [visible_with_roles(viewer)]
        if owner is not None:
            where.append(c.owner_id == owner)
        n_curves = select(func.count()).where(m.TemplateCurve.collection_id == c.id).correlate(c).scalar_subquery()
        n_members = select(func.count()).where(m.Member.collection_id == c.id).correlate(c).scalar_subquery()
        query = (
            select(
                c.id,
                c.name,
                owner_name(),
                c.owner_id,
                c.sharing,
                c.template,
                c.k,
                c.revision,
                c.created_at,
                c.updated_at,
                n_curves.label("n_curves"),
                n_members.label("n_members"),
            )
            .outerjoin(m.User, m.User.id == c.owner_id)
            .where(*where)
            .order_by(c.updated_at.desc(), c.id.desc())
        )
        with self.db.read() as conn:
            total = conn.execute(select(func.count()).select_from(c).where(*where)).scalar() or 0
            query = query.where(after_cursor(c.updated_at, c.id, cursor)) if cursor else query.offset(offset)
            rows = conn.execute(query.limit(limit + 1)).all()
        items = [CollectionSummary(**row._asdict()) for row in rows[:limit]]
        more = len(rows) > limit
        next_cursor = encode_cursor(items[-1].updated_at, items[-1].id) if more and items else None
        return Page(items, total, limit, 0 if cursor else offset, next_cursor)

    def expired_jobs(self, collection_id: str) -> dict[tuple[str, str], str]:
        """``(run id, member id) -> job id`` for the run entries whose job record has expired."""
        with self.db.read() as conn:
            rows = conn.execute(
                select(m.RunMember.run_id, m.RunMember.member_id, m.RunMember.job_name).where(
                    m.RunMember.collection_id == collection_id, m.RunMember.job_id.is_(None)
                )
            )
            return {(r.run_id, r.member_id): r.job_name for r in rows}

    # -- roles ----------------------------------------------------------------------------------------------
    def standing(self, collection_id: str, viewer: Viewer, member_id: str | None = None) -> Standing | None:
        """Where ``viewer`` stands in the collection (and who ``member_id`` is assigned to), in one query (None:
        no such collection)."""
        if not well_formed(collection_id):
            return None
        a = m.Assignment
        assignee = (
            select(a.user_id).where(a.collection_id == m.Collection.id, a.member_id == member_id).scalar_subquery()
        )
        query = _standing_query(viewer).add_columns(assignee.label("assignee"))
        with self.db.read() as conn:
            row = conn.execute(query.where(m.Collection.id == collection_id)).first()
        return None if row is None else Standing(**row._asdict())

    def member_standing(self, session_id: str, viewer: Viewer) -> Standing | None:
        """Where ``viewer`` stands in the collection the session is a member session of (None: it is none's)."""
        member_of = m.Member.collection_id == m.Collection.id
        a = m.Assignment
        assigned = (a.collection_id == m.Member.collection_id) & (a.member_id == m.Member.id)
        query = (
            _standing_query(viewer)
            .add_columns(a.user_id.label("assignee"))
            .join(m.Member, member_of)
            .outerjoin(a, assigned)
            .where(m.Member.session_id == session_id)
        )
        with self.db.read() as conn:
            row = conn.execute(query).first()
        return None if row is None else Standing(**row._asdict())

    def grants(self, collection_id: str) -> builtins.list[Grant]:
        """The roles granted in the collection, by role (owners first), then by user name."""
        r, granter = m.CollectionRole, m.User.__table__.alias("granter")
        with self.db.read() as conn:
            rows = conn.execute(
                select(m.User.name.label("user"), r.user_id, r.role, granter.c.name.label("granted_by"), r.granted_at)
                .join(m.User, m.User.id == r.user_id)
                .outerjoin(granter, granter.c.id == r.granted_by)
                .where(r.collection_id == collection_id)
            ).all()
        grants = [Grant(**row._asdict()) for row in rows]
        return sorted(grants, key=lambda g: (ROLES.index(g.role), g.user))

    def grant(self, collection_id: str, user_id: int, role: str, by: int | None) -> str | None:
        """Give ``user_id`` ``role`` in the collection (replacing the one they held); returns the one replaced. Its
        creator's role cannot change (409)."""
        if role not in ROLES:
            raise InvalidInput(f"a role is one of {', '.join(ROLES)}, got '{shown(role)}'")
        r = m.CollectionRole
        mine = (r.collection_id == collection_id) & (r.user_id == user_id)
        with self.db.write() as tx:
            creator = tx.execute(select(m.Collection.owner_id).where(m.Collection.id == collection_id)).first()
            if creator is None:
                raise UnknownCollection(collection_id)
            if creator.owner_id == user_id:
                raise Conflict(
                    f"the user who made collection {collection_id} is its owner for good; their role cannot change"
                )
            previous = tx.execute(select(r.role).where(mine)).scalar()
            tx.execute(delete(r).where(mine))
            tx.execute(
                insert(r).values(
                    collection_id=collection_id, user_id=user_id, role=role, granted_by=by, granted_at=now()
                )
            )
        return previous

    def revoke(self, collection_id: str, user_id: int) -> str | None:
        """Take ``user_id``'s role in the collection away; returns it (None: they held none)."""
        r = m.CollectionRole
        mine = (r.collection_id == collection_id) & (r.user_id == user_id)
        with self.db.write() as tx:
            previous = tx.execute(select(r.role).where(mine)).scalar()
            tx.execute(delete(r).where(mine))
        return previous

    # -- assignment -----------------------------------------------------------------------------------------
    def assignees(self, collection_id: str) -> dict[str, tuple[int, str]]:
        """``member id -> (user id, name)`` of the assigned members, in the members' order."""
        a, member = m.Assignment, m.Member
        with self.db.read() as conn:
            rows = conn.execute(
                select(a.member_id, a.user_id, m.User.name)
                .join(member, (member.collection_id == a.collection_id) & (member.id == a.member_id))
                .join(m.User, m.User.id == a.user_id)
                .where(a.collection_id == collection_id)
                .order_by(member.position)
            ).all()
        return {row.member_id: (row.user_id, row.name) for row in rows}

    def assign(self, collection_id: str, assignments: dict[str, int | None]) -> None:
        """Assign members (``member id -> user id``; None: to no one), in one transaction; 404 for a member the
        collection does not have."""
        a = m.Assignment
        with self.db.write() as tx:
            known = set(tx.execute(select(m.Member.id).where(m.Member.collection_id == collection_id)).scalars())
            unknown = sorted(set(assignments) - known)
            if unknown:
                raise NotFound(f"no member {', '.join(map(shown, unknown))} in collection {collection_id}")
            mine = (a.collection_id == collection_id) & a.member_id.in_(sorted(assignments))
            tx.execute(delete(a).where(mine))
            rows = [
                {"collection_id": collection_id, "member_id": member, "user_id": user, "assigned_at": now()}
                for member, user in assignments.items()
                if user is not None
            ]
            if rows:
                tx.execute(insert(a), rows)

    def work(self, user_id: int) -> builtins.list[Work]:
        """The members assigned to ``user_id`` and their further annotations (``further``) in every collection,
        the most recently changed collection first, members in order (a member's own session first)."""
        a, member, c, x = m.Assignment, m.Member, m.Collection, m.MemberAnnotation
        columns = (
            c.id.label("collection_id"),
            c.name.label("collection_name"),
            member.id.label("member_id"),
            member.shape,
            c.updated_at,
            member.position,
        )
        own, further = (
            select(*columns, session, flag.label("further"))
            .select_from(table)
            .join(member, (member.collection_id == table.collection_id) & (member.id == table.member_id))
            .join(c, c.id == table.collection_id)
            .where(table.user_id == user_id)
            for table, session, flag in ((a, member.session_id, false()), (x, x.session_id, true()))
        )
        both = union_all(own, further).subquery()
        order = (both.c.updated_at.desc(), both.c.collection_id, both.c.position, both.c.further)
        fields = ("collection_id", "collection_name", "member_id", "session_id", "shape", "further")
        with self.db.read() as conn:
            rows = conn.execute(select(*(both.c[f] for f in fields)).order_by(*order)).all()
        return [Work(**row._asdict()) for row in rows]

    # -- review -------------------------------------------------------------------------------------------
    def reviews(self, collection_id: str) -> dict[str, Review]:
        """``member id -> Review`` of the members that left ``open``, in the members' order."""
        r, member = m.MemberReview, m.Member
        submitter, reviewer = m.User.__table__.alias("submitter"), m.User.__table__.alias("reviewer")
        with self.db.read() as conn:
            rows = conn.execute(
                select(
                    r.member_id,
                    r.state,
                    submitter.c.name.label("submitted_by"),
                    r.submitted_at,
                    reviewer.c.name.label("reviewed_by"),
                    r.reviewed_at,
                    r.comment,
                )
                .join(member, (member.collection_id == r.collection_id) & (member.id == r.member_id))
                .outerjoin(submitter, submitter.c.id == r.submitted_by)
                .outerjoin(reviewer, reviewer.c.id == r.reviewed_by)
                .where(r.collection_id == collection_id)
                .order_by(member.position)
            ).all()
        return {row.member_id: Review(**row._asdict()) for row in rows}

    def move_review(
        self,
        collection_id: str,
        member_id: str,
        to: ReviewState,
        allowed_from: tuple[ReviewState, ...],
        by: int,
        comment: str = "",
        then: Callable[[Connection], object] | None = None,
    ) -> ReviewState:
        """Move a member's review to ``to`` (``submitted`` records the submitter, the others the reviewer and
        ``comment``) when it stands in one of ``allowed_from`` (409 otherwise, naming where it stands); returns
        the state it left. One transaction, which ``then`` joins (an announcement of the move): two reviewers
        deciding at once cannot both move it."""
        r = m.MemberReview
        mine = (r.collection_id == collection_id) & (r.member_id == member_id)
        with self.db.write() as tx:
            known = select(m.Member.id).where(m.Member.collection_id == collection_id, m.Member.id == member_id)
            if tx.execute(known).first() is None:
                raise NotFound(f"no member '{shown(member_id)}' in collection {collection_id}")
            row = tx.execute(select(r).where(mine)).first()
            state = row.state if row else "open"
            if state not in allowed_from:
                raise Conflict(
                    f"member {member_id} of collection {collection_id} is {state.replace('_', ' ')}; it can be "
                    f"moved to {to.replace('_', ' ')} from {' or '.join(s.replace('_', ' ') for s in allowed_from)}"
                )
            kept = row._asdict() if row else {"collection_id": collection_id, "member_id": member_id}
            change: dict[str, object]
            if to == "submitted":
                change = {"submitted_by": by, "submitted_at": now()}
            else:
                change = {"reviewed_by": by, "reviewed_at": now(), "comment": comment}
            tx.execute(delete(r).where(mine))
            tx.execute(insert(r).values({"comment": "", **kept, **change, "state": to}))
            if then is not None:
                then(tx)
        return state

    def locked_member(self, session_id: str) -> tuple[str, str, str] | None:
        """``(collection id, member id, review state)`` when the session is a member's whose curves may not change
        now (:data:`LOCKED_STATES`), else None."""
        with self.db.read() as conn:
            row = conn.execute(_LOCKED_MEMBER, {"session_id": session_id}).first()
        return None if row is None else (row.collection_id, row.id, row.state)

    # -- further annotations (double annotation) -------------------------------------------------------------
    def annotations(self, collection_id: str) -> builtins.list[Annotation]:
        """Every member's annotations: its own session (its assignee's, None: assigned to no one) first, then
        the further ones by annotator name; members in order."""
        a, member, x = m.Assignment, m.Member, m.MemberAnnotation
        with self.db.read() as conn:
            own = conn.execute(
                select(member.id, a.user_id, m.User.name, member.session_id)
                .outerjoin(a, (a.collection_id == member.collection_id) & (a.member_id == member.id))
                .outerjoin(m.User, m.User.id == a.user_id)
                .where(member.collection_id == collection_id)
                .order_by(member.position)
            ).all()
            further = conn.execute(
                select(x.member_id, x.user_id, m.User.name, x.session_id)
                .join(m.User, m.User.id == x.user_id)
                .where(x.collection_id == collection_id)
                .order_by(m.User.name)
            ).all()
        by_member: dict[str, builtins.list[Annotation]] = {}
        for row in own:
            by_member[row.id] = [Annotation(row.id, row.user_id, row.name, row.session_id, further=False)]
        for row in further:
            if row.member_id in by_member:
                by_member[row.member_id].append(
                    Annotation(row.member_id, row.user_id, row.name, row.session_id, further=True)
                )
        return [annotation for annotations in by_member.values() for annotation in annotations]

    def add_annotation(
        self, collection_id: str, member_id: str, user_id: int, session: SessionRecord, conn: Connection | None = None
    ) -> None:
        """Record ``session`` (stored here, in the same transaction) as ``user_id``'s further annotation of the
        member; 409 when they annotate it already."""
        x = m.MemberAnnotation
        with self.db.joined(conn) as tx:
            mine = (x.collection_id == collection_id) & (x.member_id == member_id) & (x.user_id == user_id)
            if tx.execute(select(x.session_id).where(mine)).first() is not None:
                raise Conflict(f"that user annotates member {member_id} of collection {collection_id} already")
            self.sessions.create(session, tx)
            tx.execute(
                insert(x).values(
                    collection_id=collection_id,
                    member_id=member_id,
                    user_id=user_id,
                    session_id=session.id,
                    created_at=now(),
                )
            )

    def annotation_standing(self, session_id: str, viewer: Viewer) -> Standing | None:
        """Where ``viewer`` stands in the collection the session is a further annotation in (its annotator as the
        assignee), None: it is none."""
        x = m.MemberAnnotation
        query = (
            _standing_query(viewer)
            .add_columns(x.user_id.label("assignee"))
            .join(x, x.collection_id == m.Collection.id)
            .where(x.session_id == session_id)
        )
        with self.db.read() as conn:
            row = conn.execute(query).first()
        return None if row is None else Standing(**{**row._asdict(), "assigning": True})

    def _annotation_sessions(
        self, tx: Connection, collection_id: str, member_id: str | None = None
    ) -> builtins.list[str]:
        x = m.MemberAnnotation
        where = [x.collection_id == collection_id] + ([x.member_id == member_id] if member_id else [])
        return list(tx.execute(select(x.session_id).where(*where)).scalars())

    # -- check members (ground truth) -------------------------------------------------------------------------
    def truth(self, collection_id: str, member_id: str) -> Truth | None:
        """The member's ground truth (None: it is no check member)."""
        t = m.MemberTruth
        with self.db.read() as conn:
            row = conn.execute(
                select(t.truth, m.User.name.label("set_by"), t.set_at)
                .outerjoin(m.User, m.User.id == t.set_by)
                .where(t.collection_id == collection_id, t.member_id == member_id)
            ).first()
        if row is None:
            return None
        return Truth(member_id, np.frombuffer(row.truth, dtype="<i4").astype(np.int64), row.set_by, row.set_at)

    def check_members(self, collection_id: str) -> builtins.list[str]:
        """The collection's check members (those with a ground truth), in the members' order."""
        t, member = m.MemberTruth, m.Member
        with self.db.read() as conn:
            return list(
                conn.execute(
                    select(t.member_id)
                    .join(member, (member.collection_id == t.collection_id) & (member.id == t.member_id))
                    .where(t.collection_id == collection_id)
                    .order_by(member.position)
                ).scalars()
            )

    def set_truth(self, collection_id: str, member_id: str, truth: np.ndarray, by: int | None) -> bool:
        """Give the member its ground truth (replacing one it had; returns whether it had one); 404 for a member
        the collection does not have."""
        t = m.MemberTruth
        mine = (t.collection_id == collection_id) & (t.member_id == member_id)
        with self.db.write() as tx:
            _require_member(tx, collection_id, member_id)
            had = tx.execute(delete(t).where(mine)).rowcount > 0
            data = np.asarray(truth, dtype="<i4").tobytes()
            tx.execute(
                insert(t).values(collection_id=collection_id, member_id=member_id, truth=data, set_by=by, set_at=now())
            )
        return had

    def remove_truth(self, collection_id: str, member_id: str) -> bool:
        """Take the member's ground truth away; returns whether it had one."""
        t = m.MemberTruth
        with self.db.write() as tx:
            done = tx.execute(delete(t).where(t.collection_id == collection_id, t.member_id == member_id))
        return done.rowcount > 0

    # -- what the file store offered, for a swap ------------------------------------------------------------
    lock_timeout_s = 30.0
    """How long a writer waits for another (the database's busy timeout; there are no record locks)."""

    @contextmanager
    def locked(self, record_id: str, new: bool = False) -> Iterator[None]:
        """No lock is needed (a write checks the revision it started from); raises for an unknown record as the
        file store's lock did, unless it is ``new``."""
        if not new and not self.exists(record_id):
            raise UnknownCollection(record_id)
        yield

    def list(self) -> builtins.list[CollectionRecord]:
        """Every record, the most recently changed first. Reads them all: lists for people use :meth:`page`."""
        with self.db.read() as conn:
            ids = conn.execute(
                select(m.Collection.id).order_by(m.Collection.updated_at.desc(), m.Collection.id.desc())
            ).scalars()
            return [_read(conn, record_id) for record_id in list(ids)]

    # -- changing -------------------------------------------------------------------------------------------
    def create(self, record: CollectionRecord, conn: Connection | None = None, owner: OwnerIds | None = None) -> None:
        """Store a new record as it is; its members' sessions must exist (see :meth:`add_members`)."""
        if not well_formed(record.id):
            raise InvalidInput(f"a collection id is 1-64 letters, digits, '-' or '_', got '{shown(record.id)}'")
        try:
            with self.db.joined(conn) as tx:
                if _revision(tx, record.id) is not None:
                    raise Conflict(f"collection '{record.id}' already exists")
                _require_shapes(
                    tx, self.sessions.stored_shape, record.template, *(member.shape for member in record.members)
                )
                tx.execute(
                    insert(m.Collection).values(
                        id=record.id,
                        owner_id=(owner or partial(owner_id, tx))(record.owner),
                        revision=record.revision,
                        created_at=record.created_at,
                        updated_at=record.updated_at,
                        **{name: getattr(record, name) for name in SCALARS},
                    )
                )
                _insert_children(tx, record)
        except IntegrityError as exc:
            raise Conflict(
                f"collection '{record.id}' cannot be stored: {' '.join(str(exc.orig).split())[:200]}"
            ) from None

    def write(self, record: CollectionRecord, conn: Connection | None = None) -> CollectionRecord:
        """Store ``record`` as the next revision after ``record.revision`` (:class:`StaleRevision` if the
        stored one moved on); returns what was stored."""
        written = record.model_copy(update={"revision": record.revision + 1, "updated_at": now()})
        try:
            return self._write(record, written, conn)
        except IntegrityError as exc:  # a member's session is not stored
            raise Conflict(
                f"collection '{record.id}' cannot be stored: {' '.join(str(exc.orig).split())[:200]}"
            ) from None

    def _write(self, record: CollectionRecord, written: CollectionRecord, conn: Connection | None) -> CollectionRecord:
        with self.db.joined(conn) as tx:
            done = tx.execute(
                update(m.Collection)
                .where(m.Collection.id == record.id, m.Collection.revision == record.revision)
                .values(
                    revision=written.revision,
                    updated_at=written.updated_at,
                    **{name: getattr(record, name) for name in SCALARS},
                )
            )
            if done.rowcount != 1:
                stored = _revision(tx, record.id)
                if stored is None:
                    raise UnknownCollection(record.id)
                raise StaleRevision("collection", record.id, record.revision, stored)
            _require_shapes(tx, self.sessions.stored_shape, *(member.shape for member in record.members))
            for table in (m.RunMember, m.Run, m.Member, m.TemplateCurve):
                tx.execute(delete(table).where(table.collection_id == record.id))
            _insert_children(tx, record)
        return written

    def add_members(
        self,
        collection_id: str,
        revision: int,
        added: builtins.list[tuple[Member, SessionRecord]],
        conn: Connection | None = None,
    ) -> CollectionRecord:
        """Add members with their new sessions, in one transaction (the collection at ``revision``; the caller's
        ``conn``, e.g. the one that counted them against the sessions quota): a failure leaves neither the
        sessions nor the members."""
        with self.db.joined(conn) as conn:
            record = _read(conn, collection_id)
            if record.revision != revision:
                raise StaleRevision("collection", collection_id, revision, record.revision)
            for _, session in added:
                self.sessions.create(session, conn)
            members = [*record.members, *(member for member, _ in added)]
            changed = record.model_copy(update={"members": members, "next_member": record.next_member + len(added)})
            return self.write(changed, conn)

    def remove_member(self, collection_id: str, member_id: str, conn: Connection | None = None) -> builtins.list[str]:
        """Remove a member with its session (its entries in runs go with it); returns the refinement jobs run from
        the session, whose results the caller deletes."""
        with self.db.joined(conn) as tx:
            record = _read(tx, collection_id)
            jobs: builtins.list[str] = []
            for further in self._annotation_sessions(tx, collection_id, member_id):
                jobs += self.sessions.delete(further, tx)
            session_id = record.member(member_id).session
            return jobs + self.sessions.delete(session_id, tx)  # (moves the collection to its next revision)

    def delete(self, collection_id: str, conn: Connection | None = None) -> builtins.list[str]:
        """Delete the collection, its member sessions and its further annotations' sessions; returns the refinement
        jobs run from those."""
        with self.db.joined(conn) as tx:
            if _revision(tx, collection_id) is None:
                raise UnknownCollection(collection_id)
            sessions = list(
                tx.execute(select(m.Member.session_id).where(m.Member.collection_id == collection_id)).scalars()
            )
            sessions += self._annotation_sessions(tx, collection_id)
            tx.execute(delete(m.Collection).where(m.Collection.id == collection_id))
            jobs: builtins.list[str] = []
            for session_id in sessions:
                jobs += self.sessions.delete(session_id, tx)
        return jobs

    remove = delete


def visible_with_roles(viewer: Viewer) -> ColumnElement[bool]:
    """The collections ``viewer`` may see as a WHERE clause: by owner and sharing, or a role granted to them."""
    c = m.Collection
    if viewer.user_id is None:
        return visible(c.owner_id, c.sharing, viewer)
    r = m.CollectionRole
    granted = exists().where(r.collection_id == c.id, r.user_id == viewer.user_id)
    return or_(visible(c.owner_id, c.sharing, viewer), granted)


def _standing_query(viewer: Viewer) -> Select[str, bool, str, str, bool]:
    c, r = m.Collection, m.CollectionRole
    a, member = aliased(m.Assignment), aliased(m.Member)  # (the member queries join both tables outside)
    creator = c.owner_id == viewer.user_id if viewer.user_id is not None else false()
    assigned_member = (member.collection_id == a.collection_id) & (member.id == a.member_id)
    assigning = select(a.member_id).join(member, assigned_member).where(a.collection_id == c.id).exists()
    return select(
        c.id.label("collection_id"), creator.label("creator"), c.sharing, r.role, assigning.label("assigning")
    ).outerjoin(r, and_(r.collection_id == c.id, r.user_id == viewer.user_id))


def _require_member(conn: Connection, collection_id: str, member_id: str) -> None:
    known = select(m.Member.id).where(m.Member.collection_id == collection_id, m.Member.id == member_id)
    if conn.execute(known).first() is None:
        raise NotFound(f"no member '{shown(member_id)}' in collection {collection_id}")


def _revision(conn: Connection, collection_id: str) -> int | None:
    return conn.execute(select(m.Collection.revision).where(m.Collection.id == collection_id)).scalar()


def _insert_children(conn: Connection, record: CollectionRecord) -> None:
    cid = record.id
    if record.curves:
        conn.execute(
            insert(m.TemplateCurve),
            [
                {
                    "collection_id": cid,
                    "id": c.id,
                    "position": i,
                    "name": c.name,
                    "waypoints": list(c.waypoints),
                    "path": path_bytes(c.path),
                }
                for i, c in enumerate(record.curves)
            ],
        )
    jobs = {member.basis_job for member in record.members if member.basis_job}
    jobs |= {entry.job for run in record.runs for entry in run.members.values()}
    known = _known_jobs(conn, jobs)
    if record.members:
        conn.execute(
            insert(m.Member),
            [
                {
                    "collection_id": cid,
                    "id": member.id,
                    "position": i,
                    "shape": member.shape,
                    "session_id": member.session,
                    "basis_job": member.basis_job if member.basis_job in known else None,
                }
                for i, member in enumerate(record.members)
            ],
        )
    members = {member.id for member in record.members}
    for run in record.runs:
        conn.execute(
            insert(m.Run).values(
                collection_id=cid, id=run.id, converter=run.converter, params=run.params, created_at=run.created_at
            )
        )
        entries = [
            {
                "collection_id": cid,
                "run_id": run.id,
                "member_id": member_id,
                "job_id": entry.job if entry.job in known else None,
                "job_name": entry.job,
                "revision": entry.revision,
                "carried": entry.carried,
            }
            for member_id, entry in run.members.items()
            if member_id in members  # a member whose session was deleted has left its runs
        ]
        if entries:
            conn.execute(insert(m.RunMember), entries)


def _known_jobs(conn: Connection, jobs: set[str]) -> set[str]:
    if not jobs:
        return set()
    return set(conn.execute(select(m.Job.id).where(m.Job.id.in_(sorted(jobs)))).scalars())


def _read(conn: Connection, collection_id: str) -> CollectionRecord:
    if not well_formed(collection_id):
        raise UnknownCollection(collection_id)
    columns = [c for c in m.Collection.__table__.c if c.name != "owner_id"]
    row = conn.execute(
        select(*columns, owner_name())
        .outerjoin(m.User, m.User.id == m.Collection.owner_id)
        .where(m.Collection.id == collection_id)
    ).first()
    if row is None:
        raise UnknownCollection(collection_id)
    curves = conn.execute(
        select(m.TemplateCurve).where(m.TemplateCurve.collection_id == collection_id).order_by(m.TemplateCurve.position)
    ).all()
    members = conn.execute(
        select(m.Member).where(m.Member.collection_id == collection_id).order_by(m.Member.position)
    ).all()
    runs = conn.execute(select(m.Run).where(m.Run.collection_id == collection_id).order_by(m.Run.created_at)).all()
    entries = conn.execute(
        select(m.RunMember, m.Member.position)
        .join(
            m.Member,
            (m.Member.collection_id == m.RunMember.collection_id) & (m.Member.id == m.RunMember.member_id),
        )
        .where(m.RunMember.collection_id == collection_id)
        .order_by(m.Member.position)
    ).all()
    by_run: dict[str, dict[str, RunMember]] = {}
    for e in entries:
        by_run.setdefault(e.run_id, {})[e.member_id] = RunMember(job=e.job_name, revision=e.revision, carried=e.carried)
    return CollectionRecord(
        **row._asdict(),
        curves=[TemplateCurve(id=c.id, name=c.name, waypoints=c.waypoints, path=path_array(c.path)) for c in curves],
        members=[Member(id=x.id, shape=x.shape, session=x.session_id, basis_job=x.basis_job) for x in members],
        runs=[
            Run(id=r.id, converter=r.converter, params=r.params, created_at=r.created_at, members=by_run.get(r.id, {}))
            for r in runs
        ],
    )
