"""The operations on collections: create one (from a session, or from template curves), add members (each a
session the collection makes and owns), answer a template curve on a member, share, delete, start batch runs.

Member sessions are created before their bases exist (the caller queues the basis jobs): until then a member's
curves and maps answer 409 naming the missing basis, as any session's would. Who may do which is the caller's to
decide (the API checks owner and sharing as for sessions).
"""

from __future__ import annotations

import secrets
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Literal

from curvefm.collection.record import (
    SOLVER_FIELDS,
    CollectionCreate,
    CollectionRecord,
    Member,
    Run,
    RunMember,
    TemplateCurve,
    TemplateCurveSpec,
)
from curvefm.errors import Conflict, InvalidInput
from curvefm.session import (
    NAME_LENGTH,
    CurveRecord,
    CurveSpec,
    MapSummary,
    SessionEditor,
    SessionLimits,
    SessionRecord,
    Sharing,
    trace_curve,
)
from curvefm.spectral import check_k

if TYPE_CHECKING:
    from sqlalchemy import Connection

    from curvefm.records.collections import Collections

SubmitRefine = Callable[[SessionRecord], str]
"""Queues a refinement of a member session (a snapshot of its record); returns the job id."""


class CollectionEditor:
    def __init__(self, records: Collections, sessions: SessionEditor):
        self.records, self.sessions = records, sessions

    @property
    def limits(self) -> SessionLimits:
        return self.sessions.limits

    def record(self, collection_id: str) -> CollectionRecord:
        return self.records.read(collection_id)

    # -- creating ------------------------------------------------------------------------------------------
    def create(
        self,
        request: CollectionCreate,
        owner: str = "",
        collection_id: str | None = None,
        conn: Connection | None = None,
    ) -> CollectionRecord:
        """A new collection of ``owner`` with its template curves and the members the request names (their
        sessions made with them), in the transaction ``conn`` when given (the one that counted the member sessions
        against the owner's quota), else in one of its own."""
        template_mesh = self.sessions.live.mesh(request.template, "template")
        source = self.sessions.record(request.from_session) if request.from_session else None
        solver = {name: getattr(source or request, name) for name in SOLVER_FIELDS}
        check_k(solver["k"], template_mesh.n_vertices, template_mesh.name or request.template)
        self.limits.check("max_k", solver["k"], f"k = {solver['k']} basis functions")
        self.sessions.find_plugin("tracer", solver["tracer"])
        if source is not None and source.source != request.template:
            raise Conflict(
                f"session {source.id}'s source is shape {source.source}, not the template {request.template}"
            )
        curves = _curves_of(source) if source else [self._traced(request, spec) for spec in request.curves]
        self.limits.check("max_curves", len(curves), f"{len(curves)} template curves")
        now = time.time()
        record = CollectionRecord(
            id=collection_id or secrets.token_hex(8),
            name=request.name,
            owner=owner,
            sharing=request.sharing,
            template=request.template,
            curves=[c.model_copy(update={"id": f"t{i}"}) for i, c in enumerate(curves, 1)],
            created_at=now,
            updated_at=now,
            **solver,
        )
        with self.records.db.joined(conn) as tx:
            self.records.create(record, tx)
            if source is not None:
                self._add(record.id, [source.target], first_curves=source.curves, conn=tx)
            if request.members:
                self._add(record.id, request.members, conn=tx)
            return self.records.read(record.id, tx)

    def _traced(self, request: CollectionCreate, spec: TemplateCurveSpec) -> TemplateCurve:
        mesh = self.sessions.live.mesh(request.template, "template")
        what = "vertices in the template path" if spec.explicit else "waypoints on the template"
        self.limits.check(
            "max_path_vertices" if spec.explicit else "max_waypoints",
            len(spec.waypoints),
            f"{len(spec.waypoints)} {what}",
        )
        if spec.explicit:
            path = trace_curve(mesh, path=spec.waypoints)
        else:
            path = trace_curve(mesh, spec.waypoints, tracer=spec.tracer or request.tracer, params=spec.tracer_params)
        self.limits.check("max_path_vertices", len(path), f"{len(path)} vertices in a traced template path")
        return TemplateCurve(id="new", name=spec.name, waypoints=spec.waypoints, path=mesh.file_ids[path])

    # -- members -------------------------------------------------------------------------------------------
    def add_members(self, collection_id: str, shapes: list[str], conn: Connection | None = None) -> list[Member]:
        """New members on ``shapes`` (each gets its own session, made in the same transaction: ``conn`` when
        given), last in the list."""
        return self._add(collection_id, shapes, conn=conn)

    def set_basis_job(self, collection_id: str, member_id: str, job_id: str) -> None:
        with self.records.locked(collection_id):
            record = self.record(collection_id)
            members = [m.model_copy(update={"basis_job": job_id}) if m.id == member_id else m for m in record.members]
            self.records.write(record.model_copy(update={"members": members}))

    def _add(
        self,
        collection_id: str,
        shapes: list[str],
        first_curves: Sequence[CurveRecord] = (),
        conn: Connection | None = None,
    ) -> list[Member]:
        """The members and their sessions in one transaction (``conn``, else one of its own): a refused member
        (a shape that is not stored, a limit) stores nothing."""
        if not shapes:
            raise InvalidInput("name at least one member shape")
        record = self.records.read(collection_id, conn)
        count = len(record.members) + len(shapes)
        self.limits.check("max_members", count, f"{count} members in collection {collection_id}")
        _refuse_duplicates(record, shapes, self._shape_name)
        for shape in shapes:
            mesh = self.sessions.live.mesh(shape, "member")
            check_k(record.k, mesh.n_vertices, mesh.name or shape)
        added = []
        for i, shape in enumerate(shapes):
            session = self._member_session(record, shape, first_curves)
            added.append((Member(id=f"m{record.next_member + i}", shape=shape, session=session.id), session))
        self.records.add_members(collection_id, record.revision, added, conn)
        return [member for member, _ in added]

    def add_annotation(self, collection_id: str, member_id: str, user_id: int, conn: Connection | None = None) -> str:
        """A further annotation of a member by ``user_id`` (double annotation): a new session of the collection's
        (template -> the member's shape, no curves yet) for them to answer the template curves in; returns its
        id."""
        record = self.record(collection_id)
        session = self._member_session(record, record.member(member_id).shape, ())
        self.records.add_annotation(collection_id, member_id, user_id, session, conn)
        return session.id

    def remove_member(self, collection_id: str, member_id: str) -> list[str]:
        """Remove a member with its session and its entries in runs; returns the refinement jobs run from its
        session (their results are the caller's to delete)."""
        member = self.record(collection_id).member(member_id)
        with self.sessions.live.locked(member.session):
            jobs = self.records.remove_member(collection_id, member_id)
            self.sessions.live.drop(member.session)
        self.sessions.live.notify(member.session, {"kind": "deleted", "revision": None})
        return jobs

    def _shape_name(self, shape: str) -> str:
        """The shape's name (its id's start when it has none)."""
        return self.sessions.live.mesh(shape, "member").name or shape[:12]

    def _member_session(self, record: CollectionRecord, shape: str, curves: Sequence[CurveRecord]) -> SessionRecord:
        """A new session record (template -> ``shape``) of the collection's owner, holding ``curves`` as answers
        to the template curves in order (a session the collection was made from passes its curves on)."""
        answered = [
            _answer(curve, f"c{number}", template.id)
            for number, (curve, template) in enumerate(zip(curves, record.curves, strict=False), 1)
        ]
        now = time.time()
        session = SessionRecord(
            id=secrets.token_hex(8),
            name=f"{record.name or record.id}: {self._shape_name(shape)}"[:NAME_LENGTH],
            owner=record.owner,
            sharing=record.sharing,
            source=record.template,
            target=shape,
            curves=answered,
            next_curve=len(answered) + 1,
            created_at=now,
            updated_at=now,
            **{name: getattr(record, name) for name in SOLVER_FIELDS},
        )
        return session

    def answer(
        self,
        collection_id: str,
        member_id: str,
        template_curve: str,
        target: list[int],
        expected_revision: int | None = None,
        session_id: str | None = None,
        **options: Any,
    ) -> tuple[CurveRecord, MapSummary]:
        """Answer ``template_curve`` on a member: ``target`` (waypoints on the member, or a path with
        ``explicit="target"`` in ``options``) becomes a curve of its session (``session_id``: a further
        annotation's instead) whose source is the template curve's path. A template curve answered before is
        replaced (its session curve keeps its id). Given the session's ``expected_revision``, refused when the
        session is at another."""
        record = self.record(collection_id)
        member, template = record.member(member_id), record.template_curve(template_curve)
        session_id = session_id or member.session
        explicit: bool | Literal["source"] = True if options.pop("explicit", False) else "source"
        spec = CurveSpec(
            source=template.path.tolist(), target=target, explicit=explicit, template_curve=template.id, **options
        )
        previous = [c.id for c in self.sessions.record(session_id).curves if c.spec.template_curve == template.id]
        if previous:
            return self.sessions.replace_curve(session_id, previous[0], spec, expected_revision)
        return self.sessions.add_curve(session_id, spec, expected_revision=expected_revision)

    # -- sharing and deleting ------------------------------------------------------------------------------
    def share(self, collection_id: str, sharing: Sharing) -> CollectionRecord:
        """Share the collection and its member sessions alike."""
        with self.records.locked(collection_id):
            record = self.records.write(self.record(collection_id).model_copy(update={"sharing": sharing}))
        for member in record.members:
            self.sessions.share(member.session, sharing)
        return record

    def delete(self, collection_id: str) -> list[str]:
        """Delete the collection and its member sessions (one transaction); returns the refinement jobs run from
        them."""
        sessions = [annotation.session_id for annotation in self.records.annotations(collection_id)]
        jobs = self.records.delete(collection_id)
        for session_id in sessions:
            self.sessions.live.drop(session_id)
            self.sessions.live.notify(session_id, {"kind": "deleted", "revision": None})
        return jobs

    # -- batch runs ----------------------------------------------------------------------------------------
    def start_run(
        self,
        collection_id: str,
        converter: str,
        params: dict[str, Any],
        submit: SubmitRefine,
        members: list[str] | None = None,
        only_ready: bool = False,
    ) -> Run:
        """Queue one refinement job per member (``members``, or all; ``only_ready``: those of them that have
        curves) with ``converter`` and its canonical ``params``. Members not run keep their jobs of the previous
        run when it used the same converter and parameters (``carried``), so the newest run's archive covers the
        whole collection."""
        record = self.record(collection_id)
        chosen = [record.member(m) for m in dict.fromkeys(members)] if members else record.members
        if not chosen:
            raise Conflict(f"collection {collection_id} has no members yet; add some before a run")
        sessions = {m.id: self.sessions.record(m.session) for m in chosen}
        empty = [m for m in chosen if not sessions[m.id].curves]
        if only_ready:
            sessions = {member_id: session for member_id, session in sessions.items() if session.curves}
        if not sessions:
            raise Conflict(
                f"no member of collection {collection_id} has curves yet; answer at least one template curve on "
                "a member before a run"
            )
        if empty and not only_ready:
            named = ", ".join(f"{m.id} ({self._shape_name(m.shape)})" for m in empty)
            raise Conflict(
                f"members {named} of collection {collection_id} have no curves yet; answer at least one template "
                "curve on each, or run only the members that are ready ('only_ready': true; the command line's "
                "--only-ready)"
            )
        jobs = {m: RunMember(job=submit(session), revision=session.revision) for m, session in sessions.items()}
        with self.records.locked(collection_id):
            record = self.record(collection_id)
            carried = _carried(record, converter, params, set(jobs))
            run = Run(
                id=f"r{record.next_run}",
                converter=converter,
                params=params,
                created_at=time.time(),
                members={**carried, **jobs},
            )
            self.records.write(record.model_copy(update={"runs": [*record.runs, run], "next_run": record.next_run + 1}))
        return run


def _refuse_duplicates(record: CollectionRecord, shapes: list[str], name_of: Callable[[str], str]) -> None:
    """409 for a shape that is a member already, or named twice."""
    members = {member.shape: member.id for member in record.members}
    seen: set[str] = set()
    for shape in shapes:
        if shape in members:
            raise Conflict(
                f"shape '{name_of(shape)}' ({shape}) is member {members[shape]} of collection {record.id} already; "
                "a shape is a member once"
            )
        if shape in seen:
            raise Conflict(f"shape '{name_of(shape)}' ({shape}) is named twice; a shape is a member once")
        seen.add(shape)


def _curves_of(session: SessionRecord) -> list[TemplateCurve]:
    """The source sides of a session's curves as template curves (ids are given by the caller)."""
    return [
        TemplateCurve(
            id=curve.id,
            name=curve.id,
            waypoints=[] if curve.spec.is_path("source") else curve.spec.source,
            path=curve.path_source,
        )
        for curve in session.curves
    ]


def _answer(curve: CurveRecord, curve_id: str, template_curve: str) -> CurveRecord:
    """A session curve of the collection's first member: the same paths, naming the template curve it answers."""
    spec = curve.spec.model_copy(update={"template_curve": template_curve})
    return curve.model_copy(update={"id": curve_id, "spec": spec})


def _carried(
    record: CollectionRecord, converter: str, params: dict[str, Any], run_now: set[str]
) -> dict[str, RunMember]:
    if not record.runs or (record.runs[-1].converter, record.runs[-1].params) != (converter, params):
        return {}
    previous = record.runs[-1].members
    members = {m.id for m in record.members}
    return {
        m: job.model_copy(update={"carried": True}) for m, job in previous.items() if m not in run_now and m in members
    }
