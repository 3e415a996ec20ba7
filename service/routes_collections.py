"""``/collections``: a template with its curves and many members (each a session the collection owns), batch
runs of refinement jobs over the members, a run's maps as one archive, member-to-member maps through the template.
Who may do which: as sessions (:mod:`curvefm.service.permissions`)."""

from __future__ import annotations

import io
from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, File, Response, UploadFile

from curvefm.access import User
from curvefm.collection import (
    CollectionCreate,
    CollectionRecord,
    RunStatus,
    archive_summary,
    composed,
    member_status,
    run_maps,
    run_status,
    write_npz,
    write_zip,
)
from curvefm.errors import InvalidInput, NotFound
from curvefm.service.auth import AUTHENTICATED, CurrentUser
from curvefm.service.deps import JOB_ERRORS, Services, ServicesDep, job_view, submit_basis, submit_refine
from curvefm.service.errors import error_responses
from curvefm.service.models import (
    AnswerRequest,
    CollectionSummary,
    CollectionView,
    ComposedMaps,
    CurveEdit,
    MemberMapsResponse,
    MembersRequest,
    RunRequest,
    SessionChange,
)
from curvefm.service.openapi import SchemaRoute
from curvefm.service.permissions import collection_for, may_read, session_for
from curvefm.service.routes_sessions import converter_params, discard_job
from curvefm.service.routes_shapes import store_upload
from curvefm.session import BasisNeed, basis_available

router = APIRouter(
    tags=["collections"], route_class=SchemaRoute, dependencies=AUTHENTICATED, responses=error_responses(401, 403, 503)
)
ERRORS = error_responses(400, 404, 409, 413, 422)
RUN_ERRORS = {
    **error_responses(
        400, 404, 409, 413, 422, 429, described={400: "the converter's parameters contradict each other"}
    ),
    **JOB_ERRORS,
}
ARCHIVE_TYPES = {"npz": "application/x-npz", "zip": "application/zip"}


def _binary(*media: str) -> dict:
    return {200: {"content": {m: {"schema": {"type": "string", "format": "binary"}} for m in media}}, **ERRORS}


@router.post("/collections", status_code=201, response_model=CollectionView, responses={**ERRORS, **JOB_ERRORS})
def create_collection(body: CollectionCreate, services: ServicesDep, user: CurrentUser) -> CollectionView:
    """A collection of yours on a template shape. Template curves come from a session on the template
    (``from_session``, which you may read: its source must be the template; its target becomes the first member
    with its curves) or are given as waypoints on the template (``curves``). Basis jobs are queued for the
    template and every member that lacks one (``GET /collections/{id}`` shows their state)."""
    if body.from_session:
        session_for(services, user, body.from_session, "read")
    record = services.collections.create(body, owner=user.name)
    _queue_bases(services, record, user)
    services.audit.record(user.name, "collection.create", record.id, {"members": len(record.members)})
    return _view(services, record.id)


@router.get("/collections", response_model=list[CollectionSummary])
def list_collections(services: ServicesDep, user: CurrentUser) -> list[CollectionSummary]:
    """The collections you may see: yours, those shared with the lab, and (for admins) all."""
    return [
        CollectionSummary(n_curves=len(r.curves), n_members=len(r.members),
                          **r.model_dump(include=set(CollectionSummary.model_fields) - {"n_curves", "n_members"}))
        for r in services.collections.records.list()
        if may_read(user, r)
    ]  # fmt: skip


@router.get("/collections/{collection_id}", response_model=CollectionView, responses=ERRORS)
def get_collection(collection_id: str, services: ServicesDep, user: CurrentUser) -> CollectionView:
    """The collection, and per member: its shape and session, its basis (ready or the job's state), the template
    curves answered on it, and its job in the newest run that ran it."""
    collection_for(services, user, collection_id, "read")
    return _view(services, collection_id)


@router.patch("/collections/{collection_id}", response_model=CollectionRecord, responses=ERRORS)
def change_collection(
    collection_id: str, body: SessionChange, services: ServicesDep, user: CurrentUser
) -> CollectionRecord:
    """Share the collection (and its member sessions) with the lab, or make it private: its owner or an admin."""
    collection_for(services, user, collection_id, "manage")
    record = services.collections.share(collection_id, body.sharing)
    services.audit.record(user.name, "collection.share", collection_id, {"sharing": body.sharing})
    return record


@router.delete("/collections/{collection_id}", status_code=204, responses=ERRORS)
def delete_collection(collection_id: str, services: ServicesDep, user: CurrentUser) -> Response:
    """Delete the collection, its member sessions and their refinement results: its owner or an admin."""
    collection_for(services, user, collection_id, "manage")
    for job_id in services.collections.delete(collection_id):
        discard_job(services, job_id)
    services.audit.record(user.name, "collection.delete", collection_id)
    return Response(status_code=204)


@router.post(
    "/collections/{collection_id}/members",
    status_code=201,
    response_model=CollectionView,
    responses={**ERRORS, **JOB_ERRORS},
)
def add_members(collection_id: str, body: MembersRequest, services: ServicesDep, user: CurrentUser) -> CollectionView:
    """Add stored shapes as members (each gets a session template -> member); their basis jobs are queued.
    413 past ``CURVEFM_MAX_MEMBERS``."""
    collection_for(services, user, collection_id, "edit")
    return _with_members(services, user, collection_id, body.shapes)


@router.post(
    "/collections/{collection_id}/members/upload",
    status_code=201,
    response_model=CollectionView,
    responses={
        **error_responses(400, 404, 409, 413, 422, 429, described={400: "no file, or a file that is not a mesh"}),
        **JOB_ERRORS,
    },
)
def upload_members(
    collection_id: str,
    services: ServicesDep,
    user: CurrentUser,
    files: Annotated[list[UploadFile], File(description="mesh files, one member each")] = (),
) -> CollectionView:
    """Upload several meshes at once (as ``POST /shapes`` each) and add them as members."""
    collection_for(services, user, collection_id, "edit")
    if not files:  # a multipart body without parts: the schema cannot ask for at least one
        raise InvalidInput("upload at least one mesh file (multipart field 'files')")
    shapes = [store_upload(services, user, file)[0] for file in files]
    return _with_members(services, user, collection_id, shapes)


def _with_members(services: Services, user: User, collection_id: str, shapes: list[str]) -> CollectionView:
    """Add the stored shapes as members, queue their basis jobs, and return the collection's view."""
    services.collections.add_members(collection_id, shapes)
    _queue_bases(services, services.collections.record(collection_id), user)
    return _view(services, collection_id)


@router.post(
    "/collections/{collection_id}/members/{member_id}/curves",
    status_code=201,
    response_model=CurveEdit,
    responses=ERRORS,
)
def answer_template_curve(
    collection_id: str, member_id: str, body: AnswerRequest, services: ServicesDep, user: CurrentUser
) -> CurveEdit:
    """Answer a template curve on a member: ``target`` (clicked on the member) becomes a curve of the member's
    session whose source is the template curve's path; its maps update as in a session. Answering a template
    curve again replaces the earlier answer. Extra curves (answering no template curve) go through
    ``POST /sessions/{session}/curves``; 409 while the member's basis is not ready."""
    collection_for(services, user, collection_id, "edit")
    options = body.model_dump(exclude={"template_curve", "target"})
    curve, summary = services.collections.answer(collection_id, member_id, body.template_curve, body.target, **options)
    return CurveEdit(curve=curve, map=summary)


@router.post("/collections/{collection_id}/runs", status_code=202, response_model=RunStatus, responses=RUN_ERRORS)
def start_run(collection_id: str, body: RunRequest, services: ServicesDep, user: CurrentUser) -> RunStatus:
    """Refine every member (or ``members``) as one job each on the workers, with one converter and parameters
    (as ``POST /sessions/{id}/refine``). A run is admitted once by your concurrent-jobs quota (429 at it); its
    jobs then count towards it until they end. Members left out keep their previous run's jobs."""
    record = collection_for(services, user, collection_id, "read")
    shapes = (record.template, *(m.shape for m in record.members))
    params = converter_params(services, body, shapes, f"collection {collection_id}")
    with services.quotas.admit(user, "jobs") as charge:

        def submit(session) -> str:
            info = submit_refine(services, session, body.converter, params, user.name)
            charge(info.id)
            return info.id

        run = services.collections.start_run(collection_id, body.converter, params, submit, body.members)
    services.audit.record(user.name, "collection.run", collection_id, {"run": run.id, "jobs": len(run.members)})
    return run_status(run, lambda job_id: job_view(services, job_id))


@router.get("/collections/{collection_id}/runs/{run_id}", response_model=RunStatus, responses=ERRORS)
def get_run(collection_id: str, run_id: str, services: ServicesDep, user: CurrentUser) -> RunStatus:
    """The run's state over all members (finished when every member's job finished), and each member's job."""
    record = collection_for(services, user, collection_id, "read")
    return run_status(record.run(run_id), lambda job_id: job_view(services, job_id))


@router.get(
    "/collections/{collection_id}/runs/{run_id}/archive.{kind}",
    response_class=Response,
    responses=_binary(*ARCHIVE_TYPES.values()),
)
def get_archive(
    collection_id: str, run_id: str, kind: Literal["npz", "zip"], services: ServicesDep, user: CurrentUser
) -> Response:
    """All maps of a finished run. ``npz``: ``<member>/C_template_to_member`` and ``C_member_to_template``
    (k x k), ``<member>/map_member_to_template`` (template vertex of each member vertex, file ids, -1 for none)
    and ``map_template_to_member``, and ``summary.json`` (members, shapes, sessions, quality figures). ``zip``:
    the same as ``<member>/<name>.txt`` files. 409 names the members still pending or failed."""
    record = collection_for(services, user, collection_id, "read")
    run, maps = _maps(services, record, run_id)
    out = io.BytesIO()
    (write_npz if kind == "npz" else write_zip)(out, maps, archive_summary(record, run, maps))
    filename = f"collection_{collection_id}_{run_id}.{kind}"
    headers = {"Content-Disposition": f'attachment; filename="{filename}"'}
    return Response(out.getvalue(), media_type=ARCHIVE_TYPES[kind], headers=headers)


@router.get(
    "/collections/{collection_id}/runs/{run_id}/members/{member_id}",
    response_model=MemberMapsResponse,
    responses=ERRORS,
)
def get_member_maps(
    collection_id: str, run_id: str, member_id: str, services: ServicesDep, user: CurrentUser
) -> MemberMapsResponse:
    """One member's maps from a run (as in the archive); 409 while its job has not finished."""
    record = collection_for(services, user, collection_id, "read")
    (maps,) = _maps(services, record, run_id, [member_id])[1]
    arrays = {name: array.tolist() for name, array in maps.arrays.items()}
    fields = {"member": maps.member, "shape": maps.shape, "session": maps.session, "job": maps.job}
    return MemberMapsResponse(**fields, revision=maps.revision, report=maps.report, **arrays)


@router.get(
    "/collections/{collection_id}/runs/{run_id}/members/{a}/to/{b}",
    response_model=ComposedMaps,
    responses={200: {"content": {"application/x-npz": {"schema": {"type": "string", "format": "binary"}}}}, **ERRORS},
)
def get_composed(
    collection_id: str,
    run_id: str,
    a: str,
    b: str,
    services: ServicesDep,
    user: CurrentUser,
    format: Literal["json", "npz"] = "json",
) -> ComposedMaps | Response:
    """Member a's maps to member b through the template: the pointwise map ``P_ab = P_Tb[P_aT]`` (b's vertex for
    each vertex of a, file ids) and the functional map ``C_ab = C_Tb C_aT``; ``format=npz`` for the arrays
    (``map_a_to_b``, ``C_a_to_b``). 409 while either member's job has not finished."""
    record = collection_for(services, user, collection_id, "read")
    _, (maps_a, maps_b) = _maps(services, record, run_id, [a, b])
    p2p, C = composed(maps_a, maps_b)
    if format == "npz":
        out = io.BytesIO()
        np.savez_compressed(out, map_a_to_b=p2p, C_a_to_b=C)
        return Response(out.getvalue(), media_type="application/x-npz")
    return ComposedMaps(a=a, b=b, run=run_id, map_a_to_b=p2p.tolist(), C_a_to_b=C.tolist())


def _maps(services: Services, record: CollectionRecord, run_id: str, only: list[str] | None = None):
    run = record.run(run_id)
    for member_id in only or ():
        record.member(member_id)  # an unknown member is a 404, not a pending one
        if member_id not in run.members:
            raise NotFound(f"member {member_id} is not in run {run_id}; run it (POST .../runs with members)")
    results = services.store.root / "results"
    return run, run_maps(record, run, lambda job_id: job_view(services, job_id), results, only)


def _view(services: Services, collection_id: str) -> CollectionView:
    record = services.collections.record(collection_id)
    members = [
        member_status(record, m, services.sessions.record(m.session), _basis_state(services, record, m.shape,
                                                                                    m.basis_job),
                      lambda job_id: job_view(services, job_id))
        for m in record.members
    ]  # fmt: skip
    return CollectionView(collection=record, members=members)


def _need(record: CollectionRecord, shape: str) -> BasisNeed:
    return BasisNeed(shape, "member", record.k, record.basis_plugin, record.basis_params)


def _basis_state(services: Services, record: CollectionRecord, shape: str, job_id: str | None) -> str:
    if basis_available(services.store, _need(record, shape)):
        return "ready"
    return job_view(services, job_id).state if job_id else "missing"


def _queue_bases(services: Services, record: CollectionRecord, user: User) -> None:
    """Queue the basis of the template and of each member that lacks one (deduplicated by the queue)."""
    if not basis_available(services.store, _need(record, record.template)):
        submit_basis(services, record.template, record.k, record.basis_plugin, record.basis_params, user.name)
    for member in record.members:
        if member.basis_job is None and not basis_available(services.store, _need(record, member.shape)):
            info = submit_basis(services, member.shape, record.k, record.basis_plugin, record.basis_params, user.name)
            services.collections.set_basis_job(record.id, member.id, info.id)
