"""The tables (SQLAlchemy 2 typed declarative models); the package docstring describes them as a whole.

Conventions: ids given out by curvefm are strings (``secrets.token_hex(8)``, content hashes, ``c1``/``m1``/``r1``
within their parent); users alone have a surrogate integer id, so a name removed and added again is another user.
Times are UNIX seconds (``DOUBLE``). Vertex paths are little-endian int32 bytes (4 bytes a vertex). Free-form
parameters are JSON (``JSONB`` on PostgreSQL). Foreign keys name what happens on delete; integrity that SQL cannot
say alone (a revision matching) is checked by the repositories in the same transaction.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    Double,
    ForeignKey,
    ForeignKeyConstraint,
    Index,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Text,
    text,
)
from sqlalchemy.dialects.postgresql import JSONB
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column

ID = String(64)
"""Record ids: 1-64 letters, digits, '-' or '_' (checked where they are made)."""
Json = JSON().with_variant(JSONB(), "postgresql")
ENDED_STATES = ("finished", "failed", "canceled", "lost")
ACTIVE_STATES = ("queued", "started")

NAMING = {
    "ix": "ix_%(table_name)s_%(column_0_N_name)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_N_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING)
    type_annotation_map = {dict[str, Any]: Json}


class User(Base):
    """A user: a stable id, a name unique among current users, the SHA-256 of its bearer token. A removed user's
    row stays (``removed_at`` set, token hash cleared) so what it owned keeps an owner no new user inherits."""

    __tablename__ = "users"
    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    name: Mapped[str] = mapped_column(String(64))
    admin: Mapped[bool] = mapped_column(Boolean, default=False)
    token_sha256: Mapped[str | None] = mapped_column(String(64), unique=True)
    created_at: Mapped[float] = mapped_column(Double)
    token_rotated_at: Mapped[float] = mapped_column(Double)
    removed_at: Mapped[float | None] = mapped_column(Double)
    logins_ended_at: Mapped[float | None] = mapped_column(Double)  # by a logout: older login cookies are refused
    __table_args__ = (
        Index(
            "uq_users_current_name",
            "name",
            unique=True,
            sqlite_where=text("removed_at IS NULL"),
            postgresql_where=text("removed_at IS NULL"),
        ),
    )


class ExternalIdentity(Base):
    """A user's identity at an OpenID Connect provider: the provider's ``issuer`` URL and its ``subject`` (the
    ID token's ``iss`` and ``sub``, which together never change for a person, unlike names or e-mail addresses).
    A sign-in with a new pair makes a user; later ones find it here."""

    __tablename__ = "external_identities"
    issuer: Mapped[str] = mapped_column(String(512), primary_key=True)
    subject: Mapped[str] = mapped_column(String(255), primary_key=True)  # OpenID Connect Core caps sub at 255
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
    created_at: Mapped[float] = mapped_column(Double)
    last_login_at: Mapped[float] = mapped_column(Double)


class Shape(Base):
    """A stored mesh (its blob is ``meshes/<hash>.npz``): its name (the uploaded file's; ``""`` until read from the
    blob, for shapes recorded before names were), its size, and the user its bytes are charged to (the first
    uploader). ``created_at``: its first upload."""

    __tablename__ = "shapes"
    hash: Mapped[str] = mapped_column(ID, primary_key=True)
    name: Mapped[str] = mapped_column(String(200), default="", server_default=text("''"))
    bytes: Mapped[int] = mapped_column(Integer, default=0)
    charged_to: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="RESTRICT"), index=True)
    created_at: Mapped[float] = mapped_column(Double)
    __table_args__ = (Index("ix_shapes_name", "name", "created_at"),)


class ShapeUploader(Base):
    """Who uploaded a shape (each user once), first uploader first."""

    __tablename__ = "shape_uploaders"
    shape: Mapped[str] = mapped_column(ForeignKey("shapes.hash", ondelete="CASCADE"), primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="RESTRICT"), primary_key=True, index=True)
    uploaded_at: Mapped[float] = mapped_column(Double)
    seq: Mapped[int] = mapped_column(Integer, default=0)


class Session(Base):
    """A session: a shape pair, the solver's parameters, who owns and shares it; its curves are rows of
    :class:`Curve`. ``revision`` increases with every write (each write checks the revision it started from).
    ``bytes``: what its curves store (:func:`curvefm.records.sessions.stored_bytes`), counted against the owner's
    byte quota."""

    __tablename__ = "sessions"
    id: Mapped[str] = mapped_column(ID, primary_key=True)
    name: Mapped[str] = mapped_column(String(200), default="")
    owner_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="RESTRICT"), index=True)
    sharing: Mapped[str] = mapped_column(String(8), default="private")
    source: Mapped[str] = mapped_column(ForeignKey("shapes.hash", ondelete="RESTRICT"), index=True)
    target: Mapped[str] = mapped_column(ForeignKey("shapes.hash", ondelete="RESTRICT"), index=True)
    k: Mapped[int] = mapped_column(Integer)
    alpha: Mapped[float] = mapped_column(Double)
    samples: Mapped[int] = mapped_column(Integer)
    energy: Mapped[str] = mapped_column(String(16))
    tracer: Mapped[str] = mapped_column(String(200))
    basis_plugin: Mapped[str] = mapped_column(String(200))
    basis_params: Mapped[dict[str, Any]] = mapped_column(Json)
    next_curve: Mapped[int] = mapped_column(Integer, default=1)
    revision: Mapped[int] = mapped_column(Integer, default=0)
    created_at: Mapped[float] = mapped_column(Double)
    updated_at: Mapped[float] = mapped_column(Double)
    bytes: Mapped[int] = mapped_column(Integer, default=0, server_default=text("0"))
    __table_args__ = (Index("ix_sessions_updated", "updated_at", "id"),)


class Curve(Base):
    """One curve pair of a session, at ``position`` in its list: the user's spec (JSON) and the traced paths."""

    __tablename__ = "curves"
    session_id: Mapped[str] = mapped_column(ForeignKey("sessions.id", ondelete="CASCADE"), primary_key=True)
    id: Mapped[str] = mapped_column(String(16), primary_key=True)
    position: Mapped[int] = mapped_column(Integer)
    spec: Mapped[dict[str, Any]] = mapped_column(Json)
    tracer: Mapped[str] = mapped_column(String(200))
    path_source: Mapped[bytes] = mapped_column(LargeBinary)
    path_target: Mapped[bytes] = mapped_column(LargeBinary)


class Job(Base):
    """A job: what it reports (state, progress, failure, result, times) and what it takes to run it again
    (``kwargs``, ``dedupe_key``). ``session_id``: the session a refinement ran from (kept when the session goes:
    its result is deleted by whoever deletes the session). ``result_bytes``: the size of its result files,
    counted against the owner's byte quota."""

    __tablename__ = "jobs"
    id: Mapped[str] = mapped_column(ID, primary_key=True)
    kind: Mapped[str] = mapped_column(String(16))
    state: Mapped[str] = mapped_column(String(16), index=True)
    progress: Mapped[float] = mapped_column(Double, default=0.0)
    message: Mapped[str] = mapped_column(Text, default="")
    result: Mapped[dict[str, Any] | None] = mapped_column(Json)
    error_kind: Mapped[str | None] = mapped_column(String(32))
    error_message: Mapped[str | None] = mapped_column(Text)
    worker: Mapped[str | None] = mapped_column(String(200))
    created_at: Mapped[float | None] = mapped_column(Double)
    started_at: Mapped[float | None] = mapped_column(Double)
    ended_at: Mapped[float | None] = mapped_column(Double, index=True)
    owner_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="RESTRICT"), index=True)
    kwargs: Mapped[dict[str, Any]] = mapped_column(Json)
    dedupe_key: Mapped[str | None] = mapped_column(String(200), index=True)
    runner: Mapped[str | None] = mapped_column(String(200))
    session_id: Mapped[str | None] = mapped_column(ForeignKey("sessions.id", ondelete="SET NULL"), index=True)
    result_bytes: Mapped[int] = mapped_column(Integer, default=0)


class Collection(Base):
    """A collection: a template shape with template curves, members (each a session it owns) and batch runs."""

    __tablename__ = "collections"
    id: Mapped[str] = mapped_column(ID, primary_key=True)
    name: Mapped[str] = mapped_column(String(200), default="")
    owner_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="RESTRICT"), index=True)
    sharing: Mapped[str] = mapped_column(String(8), default="private")
    template: Mapped[str] = mapped_column(ForeignKey("shapes.hash", ondelete="RESTRICT"), index=True)
    k: Mapped[int] = mapped_column(Integer)
    alpha: Mapped[float] = mapped_column(Double)
    samples: Mapped[int] = mapped_column(Integer)
    energy: Mapped[str] = mapped_column(String(16))
    tracer: Mapped[str] = mapped_column(String(200))
    basis_plugin: Mapped[str] = mapped_column(String(200))
    basis_params: Mapped[dict[str, Any]] = mapped_column(Json)
    next_member: Mapped[int] = mapped_column(Integer, default=1)
    next_run: Mapped[int] = mapped_column(Integer, default=1)
    revision: Mapped[int] = mapped_column(Integer, default=0)
    created_at: Mapped[float] = mapped_column(Double)
    updated_at: Mapped[float] = mapped_column(Double)
    __table_args__ = (Index("ix_collections_updated", "updated_at", "id"),)


class TemplateCurve(Base):
    __tablename__ = "template_curves"
    collection_id: Mapped[str] = mapped_column(ForeignKey("collections.id", ondelete="CASCADE"), primary_key=True)
    id: Mapped[str] = mapped_column(String(16), primary_key=True)
    position: Mapped[int] = mapped_column(Integer)
    name: Mapped[str] = mapped_column(String(200), default="")
    waypoints: Mapped[list[int]] = mapped_column(Json)
    """What was given on the template (file ids)."""
    path: Mapped[bytes] = mapped_column(LargeBinary)


class Member(Base):
    """A member of a collection: its shape and its session. Deleting the session removes the member (and its
    entries in runs): the collection stays readable."""

    __tablename__ = "collection_members"
    collection_id: Mapped[str] = mapped_column(ForeignKey("collections.id", ondelete="CASCADE"), primary_key=True)
    id: Mapped[str] = mapped_column(String(16), primary_key=True)
    position: Mapped[int] = mapped_column(Integer)
    shape: Mapped[str] = mapped_column(ForeignKey("shapes.hash", ondelete="RESTRICT"), index=True)
    session_id: Mapped[str] = mapped_column(ForeignKey("sessions.id", ondelete="CASCADE"), unique=True)
    basis_job: Mapped[str | None] = mapped_column(ForeignKey("jobs.id", ondelete="SET NULL"), index=True)


class Run(Base):
    __tablename__ = "collection_runs"
    collection_id: Mapped[str] = mapped_column(ForeignKey("collections.id", ondelete="CASCADE"), primary_key=True)
    id: Mapped[str] = mapped_column(String(16), primary_key=True)
    converter: Mapped[str] = mapped_column(String(200))
    params: Mapped[dict[str, Any]] = mapped_column(Json)
    created_at: Mapped[float] = mapped_column(Double)


class RunMember(Base):
    """A member's job in a run. ``job_id`` becomes NULL when the job's record expires: the run then reports the
    member's job as expired instead of failing."""

    __tablename__ = "run_members"
    collection_id: Mapped[str] = mapped_column(String(64), primary_key=True)
    run_id: Mapped[str] = mapped_column(String(16), primary_key=True)
    member_id: Mapped[str] = mapped_column(String(16), primary_key=True)
    job_id: Mapped[str | None] = mapped_column(ForeignKey("jobs.id", ondelete="SET NULL"), index=True)
    job_name: Mapped[str] = mapped_column(ID)
    """The job's id as the run was given it (kept after the job's record expired)."""
    revision: Mapped[int] = mapped_column(Integer)
    carried: Mapped[bool] = mapped_column(Boolean, default=False)
    __table_args__ = (
        ForeignKeyConstraint(
            ["collection_id", "run_id"],
            ["collection_runs.collection_id", "collection_runs.id"],
            ondelete="CASCADE",
            name="fk_run_members_run",
        ),
        ForeignKeyConstraint(
            ["collection_id", "member_id"],
            ["collection_members.collection_id", "collection_members.id"],
            ondelete="CASCADE",
            name="fk_run_members_member",
        ),
    )


class AuditEvent(Base):
    """Who did what: ``actor`` as given (a user name, ``cli``), ``user_id`` when the actor is a current user."""

    __tablename__ = "audit"
    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    time: Mapped[float] = mapped_column(Double, index=True)
    actor: Mapped[str] = mapped_column(String(64), index=True)
    user_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="RESTRICT"), index=True)
    action: Mapped[str] = mapped_column(String(64))
    target: Mapped[str] = mapped_column(String(200))
    detail: Mapped[dict[str, Any]] = mapped_column(Json)


class LegacyImport(Base):
    """Each import of a data directory in the JSON layout (:mod:`curvefm.records.legacy_import`)."""

    __tablename__ = "legacy_imports"
    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    source: Mapped[str] = mapped_column(Text)
    imported_at: Mapped[float] = mapped_column(Double)
    counts: Mapped[dict[str, Any]] = mapped_column(Json)


class CollectionRole(Base):
    """A user's role in a collection (a project): ``owner``, ``manager``, ``annotator``, ``reviewer`` or
    ``viewer`` (:mod:`curvefm.service.permissions` says what each may do). The collection's creator is its owner
    without a row; a user has one role per collection."""

    __tablename__ = "collection_roles"
    collection_id: Mapped[str] = mapped_column(ForeignKey("collections.id", ondelete="CASCADE"), primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), primary_key=True, index=True)
    role: Mapped[str] = mapped_column(String(16))
    granted_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    granted_at: Mapped[float] = mapped_column(Double)


class Assignment(Base):
    """A member assigned to an annotator. Keyed by the member's id, not a foreign key to ``collection_members``
    (whose rows a collection's write replaces); member ids are never reused, so the row of a removed member is
    inert, and reads join the members."""

    __tablename__ = "member_assignments"
    collection_id: Mapped[str] = mapped_column(ForeignKey("collections.id", ondelete="CASCADE"), primary_key=True)
    member_id: Mapped[str] = mapped_column(String(16), primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
    assigned_at: Mapped[float] = mapped_column(Double)


class SessionViewer(Base):
    """An open event stream of a session (a page showing it): whose, and until when it counts as open. Its API
    process pushes ``expires_at`` on while the stream lasts; a process that died leaves rows that expire."""

    __tablename__ = "session_viewers"
    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    session_id: Mapped[str] = mapped_column(ForeignKey("sessions.id", ondelete="CASCADE"), index=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
    opened_at: Mapped[float] = mapped_column(Double)
    expires_at: Mapped[float] = mapped_column(Double, index=True)


class Webhook(Base):
    """A URL that receives a signed JSON POST when one of ``events`` (a list of event names) happens in the
    collection. ``secret`` signs the bodies (HMAC-SHA256), so it is kept as given out, not hashed."""

    __tablename__ = "webhooks"
    id: Mapped[str] = mapped_column(ID, primary_key=True)
    collection_id: Mapped[str] = mapped_column(ForeignKey("collections.id", ondelete="CASCADE"), index=True)
    url: Mapped[str] = mapped_column(Text)
    secret: Mapped[str] = mapped_column(String(128))
    events: Mapped[list[str]] = mapped_column(Json)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    created_at: Mapped[float] = mapped_column(Double)


class WebhookDelivery(Base):
    """One event for one webhook (an outbox row, written in the transaction of the change it announces):
    ``pending`` until an API process posts it (``lease_until``: claimed by one until then), then ``delivered``
    or, after its last attempt, ``failed``; ``last_*`` say how its last attempt went."""

    __tablename__ = "webhook_deliveries"
    id: Mapped[str] = mapped_column(ID, primary_key=True)
    webhook_id: Mapped[str] = mapped_column(ForeignKey("webhooks.id", ondelete="CASCADE"), index=True)
    event: Mapped[str] = mapped_column(String(32))
    event_key: Mapped[str | None] = mapped_column(String(200), index=True)
    """Names an occurrence that two processes may both see (a run's end): it is delivered once."""
    body: Mapped[str] = mapped_column(Text)
    """The JSON posted, as signed."""
    state: Mapped[str] = mapped_column(String(16))
    attempts: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[float] = mapped_column(Double)
    next_attempt_at: Mapped[float] = mapped_column(Double)
    lease_until: Mapped[float | None] = mapped_column(Double)
    last_attempt_at: Mapped[float | None] = mapped_column(Double)
    last_status: Mapped[int | None] = mapped_column(Integer)
    last_error: Mapped[str | None] = mapped_column(Text)
    __table_args__ = (Index("ix_webhook_deliveries_due", "state", "next_attempt_at"),)


class MemberReview(Base):
    """Where a member stands in review: ``submitted``, ``changes_requested`` or ``accepted`` (no row: ``open``),
    who submitted it and when, who reviewed it last, when, and their comment. Keyed by the member's id as
    :class:`Assignment` is (member ids are never reused). Every transition is in the audit log as well."""

    __tablename__ = "member_reviews"
    collection_id: Mapped[str] = mapped_column(ForeignKey("collections.id", ondelete="CASCADE"), primary_key=True)
    member_id: Mapped[str] = mapped_column(String(16), primary_key=True)
    state: Mapped[str] = mapped_column(String(20))
    submitted_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    submitted_at: Mapped[float | None] = mapped_column(Double)
    reviewed_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    reviewed_at: Mapped[float | None] = mapped_column(Double)
    comment: Mapped[str] = mapped_column(Text, default="")


class MemberAnnotation(Base):
    """A further, independent annotation of a member by another annotator (double annotation): a session of its
    own (template -> the member's shape) whose curves that annotator answers; the member's own session is its
    assignee's. Deleting the session removes the row; the collection's and the member's deletion delete the
    session."""

    __tablename__ = "member_annotations"
    collection_id: Mapped[str] = mapped_column(ForeignKey("collections.id", ondelete="CASCADE"), primary_key=True)
    member_id: Mapped[str] = mapped_column(String(16), primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), primary_key=True, index=True)
    session_id: Mapped[str] = mapped_column(ForeignKey("sessions.id", ondelete="CASCADE"), unique=True)
    created_at: Mapped[float] = mapped_column(Double)


class ReviewComment(Base):
    """A comment on a member pinned to a vertex (a file id) of either shape of its session: ``source`` (the
    template) or ``target`` (the member's shape). A reply names its thread's first comment (``reply_to``) and sits
    where it does; a thread is resolved on its first comment. Keyed by the member's id as :class:`Assignment` is."""

    __tablename__ = "review_comments"
    id: Mapped[str] = mapped_column(ID, primary_key=True)
    collection_id: Mapped[str] = mapped_column(ForeignKey("collections.id", ondelete="CASCADE"))
    member_id: Mapped[str] = mapped_column(String(16))
    side: Mapped[str] = mapped_column(String(8))
    vertex: Mapped[int] = mapped_column(Integer)
    text: Mapped[str] = mapped_column(Text)
    author_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"), index=True)
    created_at: Mapped[float] = mapped_column(Double)
    reply_to: Mapped[str | None] = mapped_column(ForeignKey("review_comments.id", ondelete="CASCADE"), index=True)
    resolved_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    resolved_at: Mapped[float | None] = mapped_column(Double)
    __table_args__ = (Index("ix_review_comments_member", "collection_id", "member_id", "created_at"),)


class MemberTruth(Base):
    """A check member's ground truth: for every template vertex (file ids, in order) the member vertex it
    corresponds to (file id, -1: unknown), as little-endian int32 bytes, and who gave it when. Its presence makes
    the member a check member. Keyed by the member's id like :class:`Assignment` (member rows are replaced on a
    collection's write; member ids are never reused), so a removed member's row is inert."""

    __tablename__ = "member_truths"
    collection_id: Mapped[str] = mapped_column(ForeignKey("collections.id", ondelete="CASCADE"), primary_key=True)
    member_id: Mapped[str] = mapped_column(String(16), primary_key=True)
    truth: Mapped[bytes] = mapped_column(LargeBinary)
    set_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    set_at: Mapped[float] = mapped_column(Double)
