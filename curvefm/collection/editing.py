"""The operations on collections: create one (from a session, or from template curves), add members (each a
session the collection makes and owns), answer a template curve on a member, share, delete, start batch runs.

Member sessions are created before their bases exist (the caller queues the basis jobs): until then a member's
curves and maps answer 409 naming the missing basis, as any session's would. Who may do which is the caller's to
decide (the API checks owner and sharing as for sessions).
"""

from __future__ import annotations

import secrets
import time
from collections.abc import Callable

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
from curvefm.collection.store import CollectionStore
from curvefm.errors import Conflict, InvalidInput
from curvefm.session import CurveRecord, CurveSpec, MapSummary, SessionEditor, SessionRecord, Sharing, trace_curve
from curvefm.spectral import check_k

SubmitRefine = Callable[[SessionRecord], str]
"""Queues a refinement of a member session (a snapshot of its record); returns the job id."""


class CollectionEditor:
    def __init__(self, records: CollectionStore, sessions: SessionEditor):
        self.records, self.sessions = records, sessions

    @property
    def limits(self):
        return self.sessions.limits

    def record(self, collection_id: str) -> CollectionRecord:
        return self.records.read(collection_id)

    # -- creating ------------------------------------------------------------------------------------------
    def create(self, request: CollectionCreate, owner: str = "", collection_id: str | None = None) -> CollectionRecord:
        """A new collection of ``owner`` with its template curves and the members the request names."""
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
            id=collection_id or secrets.token_hex(8), name=request.name, owner=owner, sharing=request.sharing,
            template=request.template, curves=[c.model_copy(update={"id": f"t{i}"}) for i, c in
                                               enumerate(curves, 1)], created_at=now, updated_at=now, **solver,
        )  # fmt: skip
        self.records.create(record)
        if source is not None:
            self._add(record.id, [source.target], first_curves=source.curves)
        if request.members:
            self._add(record.id, request.members)
        return self.record(record.id)

    def _traced(self, request: CollectionCreate, spec: TemplateCurveSpec) -> TemplateCurve:
        mesh = self.sessions.live.mesh(request.template, "template")
        what = "vertices in the template path" if spec.explicit else "waypoints on the template"
        self.limits.check("max_path_vertices" if spec.explicit else "max_waypoints", len(spec.waypoints),
                          f"{len(spec.waypoints)} {what}")  # fmt: skip
        if spec.explicit:
            path = trace_curve(mesh, path=spec.waypoints)
        else:
            path = trace_curve(mesh, spec.waypoints, tracer=spec.tracer or request.tracer, params=spec.tracer_params)
        self.limits.check("max_path_vertices", len(path), f"{len(path)} vertices in a traced template path")
        return TemplateCurve(id="new", name=spec.name, waypoints=spec.waypoints, path=mesh.file_ids[path])

    # -- members -------------------------------------------------------------------------------------------
    def add_members(self, collection_id: str, shapes: list[str]) -> list[Member]:
        """New members on ``shapes`` (each gets its own session), last in the list."""
        return self._add(collection_id, shapes)

    def set_basis_job(self, collection_id: str, member_id: str, job_id: str) -> None:
        with self.records.locked(collection_id):
            record = self.record(collection_id)
            members = [m.model_copy(update={"basis_job": job_id}) if m.id == member_id else m for m in record.members]
            self.records.write(record.model_copy(update={"members": members}))

    def _add(self, collection_id: str, shapes: list[str], first_curves: list[CurveRecord] = ()) -> list[Member]:
        if not shapes:
            raise InvalidInput("name at least one member shape")
        record = self.record(collection_id)
        count = len(record.members) + len(shapes)
        self.limits.check("max_members", count, f"{count} members in collection {collection_id}")
        for shape in shapes:
            mesh = self.sessions.live.mesh(shape, "member")
            check_k(record.k, mesh.n_vertices, mesh.name or shape)
        with self.records.locked(collection_id):
            record = self.record(collection_id)
            self.limits.check("max_members", len(record.members) + len(shapes), f"members in {collection_id}")
            added = [
                Member(id=f"m{record.next_member + i}", shape=shape, session=self._member_session(record, shape,
                                                                                                  first_curves))
                for i, shape in enumerate(shapes)
            ]  # fmt: skip
            changes = {"members": [*record.members, *added], "next_member": record.next_member + len(added)}
            self.records.write(record.model_copy(update=changes))
        return added

    def _member_session(self, record: CollectionRecord, shape: str, curves: list[CurveRecord]) -> str:
        """A session (template -> ``shape``) of the collection's owner, holding ``curves`` as answers to the
        template curves in order (a session the collection was made from passes its curves on)."""
        answered = [
            _answer(curve, f"c{number}", template.id)
            for number, (curve, template) in enumerate(zip(curves, record.curves, strict=False), 1)
        ]
        now = time.time()
        session = SessionRecord(
            id=secrets.token_hex(8), name=f"{record.name or record.id}: {shape[:12]}", owner=record.owner,
            sharing=record.sharing, source=record.template, target=shape, curves=answered,
            next_curve=len(answered) + 1, created_at=now, updated_at=now,
            **{name: getattr(record, name) for name in SOLVER_FIELDS},
        )  # fmt: skip
        self.sessions.records.create(session)
        return session.id

    def answer(
        self, collection_id: str, member_id: str, template_curve: str, target: list[int], **options
    ) -> tuple[CurveRecord, MapSummary]:
        """Answer ``template_curve`` on a member: ``target`` (waypoints on the member, or a path with
        ``explicit="target"`` in ``options``) becomes a curve of its session whose source is the template curve's
        path. A template curve answered before is replaced (its session curve keeps its id)."""
        record = self.record(collection_id)
        member, template = record.member(member_id), record.template_curve(template_curve)
        explicit = True if options.pop("explicit", False) else "source"
        spec = CurveSpec(source=template.path.tolist(), target=target, explicit=explicit,
                         template_curve=template.id, **options)  # fmt: skip
        previous = [c.id for c in self.sessions.record(member.session).curves if c.spec.template_curve == template.id]
        if previous:
            return self.sessions.replace_curve(member.session, previous[0], spec)
        return self.sessions.add_curve(member.session, spec)

    # -- sharing and deleting ------------------------------------------------------------------------------
    def share(self, collection_id: str, sharing: Sharing) -> CollectionRecord:
        """Share the collection and its member sessions alike."""
        with self.records.locked(collection_id):
            record = self.records.write(self.record(collection_id).model_copy(update={"sharing": sharing}))
        for member in record.members:
            self.sessions.share(member.session, sharing)
        return record

    def delete(self, collection_id: str) -> list[str]:
        """Delete the collection and its member sessions; returns the refinement jobs run from them."""
        record = self.record(collection_id)
        with self.records.locked(collection_id):
            self.records.remove(collection_id)
        jobs = []
        for member in record.members:
            if self.sessions.records.exists(member.session):
                jobs += self.sessions.delete(member.session)
        return jobs

    # -- batch runs ----------------------------------------------------------------------------------------
    def start_run(
        self, collection_id: str, converter: str, params: dict, submit: SubmitRefine, members: list[str] | None = None
    ) -> Run:
        """Queue one refinement job per member (``members``, or all) with ``converter`` and its canonical
        ``params``. Members not named keep their jobs of the previous run when it used the same converter and
        parameters (``carried``), so the newest run's archive covers the whole collection."""
        record = self.record(collection_id)
        chosen = [record.member(m) for m in dict.fromkeys(members)] if members else record.members
        if not chosen:
            raise Conflict(f"collection {collection_id} has no members yet; add some before a run")
        sessions = {m.id: self.sessions.record(m.session) for m in chosen}
        empty = [member_id for member_id, session in sessions.items() if not session.curves]
        if empty:
            raise Conflict(
                f"members {', '.join(empty)} of collection {collection_id} have no curves yet; answer at "
                "least one template curve on each, or name the members to run in 'members'"
            )
        jobs = {m: RunMember(job=submit(session), revision=session.revision) for m, session in sessions.items()}
        with self.records.locked(collection_id):
            record = self.record(collection_id)
            carried = _carried(record, converter, params, set(jobs))
            run = Run(id=f"r{record.next_run}", converter=converter, params=params, created_at=time.time(),
                      members={**carried, **jobs})  # fmt: skip
            self.records.write(record.model_copy(update={"runs": [*record.runs, run], "next_run": record.next_run + 1}))
        return run


def _curves_of(session: SessionRecord) -> list[TemplateCurve]:
    """The source sides of a session's curves as template curves (ids are given by the caller)."""
    return [
        TemplateCurve(id=curve.id, name=curve.id, waypoints=[] if curve.spec.is_path("source") else curve.spec.source,
                      path=curve.path_source)
        for curve in session.curves
    ]  # fmt: skip


def _answer(curve: CurveRecord, curve_id: str, template_curve: str) -> CurveRecord:
    """A session curve of the collection's first member: the same paths, naming the template curve it answers."""
    spec = curve.spec.model_copy(update={"template_curve": template_curve})
    return curve.model_copy(update={"id": curve_id, "spec": spec})


def _carried(record: CollectionRecord, converter: str, params: dict, run_now: set[str]) -> dict[str, RunMember]:
    if not record.runs or (record.runs[-1].converter, record.runs[-1].params) != (converter, params):
        return {}
    previous = record.runs[-1].members
    members = {m.id for m in record.members}
    return {m: job.model_copy(update={"carried": True}) for m, job in previous.items()
            if m not in run_now and m in members}  # fmt: skip
