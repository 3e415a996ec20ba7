"""``/sessions``: a shape pair, its curves, the maps both ways, transfers and refinement jobs; sharing and
deleting. Who may do which: :mod:`curvefm.service.permissions`."""

from __future__ import annotations

import contextlib
import io
import shutil
from pathlib import Path
from typing import Annotated, Literal

from fastapi import APIRouter, Query, Response
from starlette.concurrency import run_in_threadpool

from curvefm.errors import Conflict, CurvefmError
from curvefm.geometry import save_textured_zip
from curvefm.matching import save_maps_mat
from curvefm.service.auth import AUTHENTICATED, CurrentUser
from curvefm.service.deps import JOB_ERRORS, Services, ServicesDep, job_model, results_dir, submit_refine
from curvefm.service.errors import error_responses, require_plugin
from curvefm.service.models import (
    CurveEdit,
    JobInfoModel,
    MapResponse,
    RefineRequest,
    SessionChange,
    SessionSummary,
)
from curvefm.service.openapi import SchemaRoute
from curvefm.service.permissions import job_for, may_read, session_for
from curvefm.session import CurveSpec, SessionCreate, SessionRecord, TransferFunction
from curvefm.spectral import check_k

router = APIRouter(  # 503: a session busy for longer than CURVEFM_SESSION_LOCK_TIMEOUT
    tags=["sessions"], route_class=SchemaRoute, dependencies=AUTHENTICATED, responses=error_responses(401, 403, 503)
)
ERRORS = error_responses(400, 404, 409, 413, 422)
QUOTA_ERRORS = error_responses(400, 404, 409, 413, 422, 429)
REFINE_ERRORS = error_responses(
    400,
    404,
    409,
    413,
    422,
    429,
    described={400: "the converter's parameters contradict each other, e.g. k_final < k_init"},
)

MAX_CURVES_POSITION = 10**6  # beyond any list (max_curves bounds it): a position past the end means last


@router.post("/sessions", status_code=201, response_model=SessionRecord, responses=QUOTA_ERRORS)
def create_session(body: SessionCreate, services: ServicesDep, user: CurrentUser) -> SessionRecord:
    """Create a session of yours on two shapes (private unless ``sharing`` says otherwise). Both need a basis
    with at least ``k`` functions already (409 names the missing ones and how to request them). 429 at your
    sessions quota."""
    with services.quotas.admit(user, "sessions") as charge:
        record = services.sessions.create(body, owner=user.name)
        charge(record.id)
    services.audit.record(user.name, "session.create", record.id, {"sharing": record.sharing})
    return record


@router.get("/sessions", response_model=list[SessionSummary])
def list_sessions(services: ServicesDep, user: CurrentUser) -> list[SessionSummary]:
    """The sessions you may see: yours, those shared with the lab, and (for admins) all."""
    return [
        SessionSummary(n_curves=len(r.curves), **r.model_dump(include=set(SessionSummary.model_fields) - {"n_curves"}))
        for r in services.records.list()
        if may_read(user, r)
    ]


@router.get("/sessions/{session_id}", response_model=SessionRecord, responses=ERRORS)
def get_session(session_id: str, services: ServicesDep, user: CurrentUser) -> SessionRecord:
    return session_for(services, user, session_id, "read")


@router.patch("/sessions/{session_id}", response_model=SessionRecord, responses=ERRORS)
def change_session(session_id: str, body: SessionChange, services: ServicesDep, user: CurrentUser) -> SessionRecord:
    """Share the session with the lab (``read`` or ``edit``) or make it ``private`` again: its owner or an admin."""
    session_for(services, user, session_id, "manage")
    record = services.sessions.share(session_id, body.sharing)
    services.audit.record(user.name, "session.share", session_id, {"sharing": body.sharing})
    return record


@router.delete("/sessions/{session_id}", status_code=204, responses=ERRORS)
def delete_session(session_id: str, services: ServicesDep, user: CurrentUser) -> Response:
    """Delete the session and the result files of its refinement jobs (running ones are canceled first): its
    owner or an admin."""
    session_for(services, user, session_id, "manage")
    for job_id in services.sessions.delete(session_id):
        discard_job(services, job_id)
    services.audit.record(user.name, "session.delete", session_id)
    return Response(status_code=204)


# The curve edits are the hot path: async routes doing their blocking work (locks, tracing, the durable write) in
# one trip to the thread pool; a plain route would take a second trip to validate its response.
@router.post("/sessions/{session_id}/curves", status_code=201, response_model=CurveEdit, responses=ERRORS)
async def add_curve(
    session_id: str,
    body: CurveSpec,
    services: ServicesDep,
    user: CurrentUser,
    curve_id: Annotated[
        str | None,
        Query(
            pattern=r"^c[1-9][0-9]{0,8}$",
            description="undoing a delete: the deleted curve's id (409 if the "
            "session never handed it out or a curve holds it); by default the next id",
        ),
    ] = None,
    position: Annotated[
        int | None,
        Query(ge=0, le=MAX_CURVES_POSITION, description="where in the curve list (0: first); by default last"),
    ] = None,
) -> CurveEdit:
    """Trace a curve pair (waypoints joined by the tracer, or ``explicit`` vertex paths; file ids), update
    both maps, store the session, then answer with the traced paths and the new map summary."""

    def edit() -> CurveEdit:
        session_for(services, user, session_id, "edit")
        curve, summary = services.sessions.add_curve(session_id, body, curve_id, position)
        return CurveEdit(curve=curve, map=summary)

    return await run_in_threadpool(edit)


@router.put("/sessions/{session_id}/curves/{curve_id}", response_model=CurveEdit, responses=ERRORS)
async def replace_curve(
    session_id: str, curve_id: str, body: CurveSpec, services: ServicesDep, user: CurrentUser
) -> CurveEdit:
    def edit() -> CurveEdit:
        session_for(services, user, session_id, "edit")
        curve, summary = services.sessions.replace_curve(session_id, curve_id, body)
        return CurveEdit(curve=curve, map=summary)

    return await run_in_threadpool(edit)


@router.delete("/sessions/{session_id}/curves/{curve_id}", response_model=CurveEdit, responses=ERRORS)
async def remove_curve(session_id: str, curve_id: str, services: ServicesDep, user: CurrentUser) -> CurveEdit:
    def edit() -> CurveEdit:
        session_for(services, user, session_id, "edit")
        return CurveEdit(map=services.sessions.remove_curve(session_id, curve_id))

    return await run_in_threadpool(edit)


@router.get("/sessions/{session_id}/map", response_model=MapResponse, responses=ERRORS)
def get_map(session_id: str, services: ServicesDep, user: CurrentUser) -> MapResponse:
    session_for(services, user, session_id, "read")
    C_MN, C_NM, record = services.sessions.maps(session_id)
    return MapResponse(
        revision=record.revision,
        k=len(C_MN),
        C_source_to_target=C_MN.tolist(),
        C_target_to_source=C_NM.tolist(),
    )


def _float32_rows(headers: dict) -> dict:
    """The responses of a route answering float32 rows per target vertex, with ``headers``."""
    binary = {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}}
    return {200: {"content": binary, "headers": headers}, **ERRORS}


FILE_IDS = r"^[0-9]{1,10}(,[0-9]{1,10})*$"  # ten digits at most: no id beyond int64 reaches numpy
RESOLUTION = Query(
    description="full: a row per target vertex; display: a row per vertex of the target as GET "
    "/shapes/{id}/mesh draws it (its display copy when it has one), as the web UI asks"
)
TRANSFER_HEADERS = {
    "X-Shape": {"description": "n,d: rows (target vertices) and values per row", "schema": {"type": "string"}},
    "X-Revision": {"description": "the session revision the map had", "schema": {"type": "string"}},
    "X-Solve-Ms": {
        "description": "milliseconds this request spent solving the map (0: already solved)",
        "schema": {"type": "string"},
    },
    "X-Prior-Pending": {
        "description": "true while the combined energy's landmark prior for the current curves is being computed "
        "(about a second): the map for this revision will still improve, so read again shortly; else false",
        "schema": {"type": "string", "enum": ["true", "false"]},
    },
}


@router.get("/sessions/{session_id}/transfer", response_class=Response, responses=_float32_rows(TRANSFER_HEADERS))
def get_transfer(
    session_id: str,
    services: ServicesDep,
    user: CurrentUser,
    function: TransferFunction = "uv",
    vertices: Annotated[
        str | None,
        Query(pattern=FILE_IDS, description="for function=indicator: comma-separated source file ids"),
    ] = None,
    resolution: Annotated[Literal["full", "display"], RESOLUTION] = "full",
) -> Response:
    """A function on the source carried to the target through the current map: float32 little-endian,
    ``n x d`` row-major with one row per target vertex in internal order. Headers: ``X-Shape: n,d``,
    ``X-Revision``, ``X-Solve-Ms`` (the map is solved on its first read after an edit) and ``X-Prior-Pending``.
    ``uv``: the source's texture coordinates (or generated cylindrical ones); ``xyz``: source coordinates scaled
    to [0, 1] per axis; ``indicator``: 1 on ``vertices``, 0 elsewhere.

    ``resolution=display``: one row per vertex that ``GET /shapes/{id}/mesh`` draws (for a big target, the rows of
    its display copy, in its order: the same values as the full rows at its ``vertex_ids``, and much cheaper to
    compute), and the indicator's ``vertices``, picked on the source as drawn, each stand for the part of the
    source nearest to them (so a region picked on a display copy covers the surface it shows). The default,
    ``full``, gives every row whatever the size."""
    session_for(services, user, session_id, "read")
    carried = services.sessions.transfer(session_id, function, _parse_ids(vertices), display=resolution == "display")
    values = carried.rows
    headers = {
        "X-Shape": f"{values.shape[0]},{values.shape[1]}",
        "X-Revision": str(carried.revision),
        "X-Solve-Ms": f"{carried.solve_ms:.3f}",
        "X-Prior-Pending": "true" if carried.prior_pending else "false",
    }
    return Response(values.astype("<f4").tobytes(), media_type="application/octet-stream", headers=headers)


QUALITY_HEADERS = {
    "X-Shape": {"description": "n,1: rows (target vertices)", "schema": {"type": "string"}},
    "X-Revision": {"description": "the session revision the maps had", "schema": {"type": "string"}},
    "X-Score": {
        "description": "the drift averaged over the target's area, in units of sqrt(area): 0 when the maps are "
        "exact inverses; lower is better",
        "schema": {"type": "string"},
    },
    **{
        f"X-Worst-{role.title()}": {
            "description": f"file id of the {role} vertex that drifts furthest",
            "schema": {"type": "string"},
        }
        for role in ("target", "source")
    },
}


@router.get("/sessions/{session_id}/quality", response_class=Response, responses=_float32_rows(QUALITY_HEADERS))
def get_quality(
    session_id: str,
    services: ServicesDep,
    user: CurrentUser,
    resolution: Annotated[Literal["full", "display"], RESOLUTION] = "full",
) -> Response:
    """How well the live maps agree, without ground truth: each target vertex carried to the source by ``C_NM``
    and back by ``C_MN`` should land where it started; how far it lands (its *drift*, in units of the target's
    sqrt(area)) is returned as float32 little-endian, one row per target vertex in internal order (with
    ``resolution=display``, per vertex that ``GET /shapes/{id}/mesh`` draws, as for the transfer). Large drift
    marks where no curve constrains the maps yet: the vertex that drifts furthest on each shape (headers
    ``X-Worst-Target``, ``X-Worst-Source``, file ids, of the whole shapes) is where a new curve helps most.
    ``X-Score`` is the area-weighted mean drift on the whole target; ``X-Revision`` the session revision."""
    session_for(services, user, session_id, "read")
    quality = services.sessions.quality(session_id, display=resolution == "display")
    headers = {
        "X-Shape": f"{len(quality.drift)},1",
        "X-Revision": str(quality.revision),
        "X-Score": f"{quality.score:.6g}",
        "X-Worst-Target": str(quality.worst_target),
        "X-Worst-Source": str(quality.worst_source),
    }
    return Response(quality.drift.astype("<f4").tobytes(), media_type="application/octet-stream", headers=headers)


EXPORT_TYPES = {"maps.mat": "application/x-matlab-data", "target_textured.zip": "application/zip"}
ExportName = Literal["maps.mat", "target_textured.zip"]


@router.get(
    "/sessions/{session_id}/exports/{export}",
    response_class=Response,
    responses={
        200: {
            "content": {media: {"schema": {"type": "string", "format": "binary"}} for media in EXPORT_TYPES.values()},
            "headers": {"X-Revision": TRANSFER_HEADERS["X-Revision"]},
        },
        **ERRORS,
    },
)
def get_export(session_id: str, export: ExportName, services: ServicesDep, user: CurrentUser) -> Response:
    """The live map as a file to download. ``maps.mat``: both functional maps for MATLAB
    (``C_source_to_target``, ``C_target_to_source``); ``target_textured.zip``: the target with the source's
    texture coordinates carried by the map, as OBJ + MTL + texture image (the UI's checkerboard). Pointwise maps
    come from a refinement job, whose files include the same two."""
    record = session_for(services, user, session_id, "read")
    out = io.BytesIO()
    if export == "maps.mat":
        C_MN, C_NM, record = services.sessions.maps(session_id)
        save_maps_mat(out, C_MN, C_NM)
        revision = record.revision
    else:
        services.sessions.maps(session_id)  # the final map: its landmark prior computed
        carried = services.sessions.transfer(session_id, "uv")
        uv, revision = carried.rows, carried.revision
        save_textured_zip(services.live.mesh(record.target), uv, out, "target_textured")
    filename = f"{Path(export).stem}_{session_id}_r{revision}{Path(export).suffix}"
    headers = {"Content-Disposition": f'attachment; filename="{filename}"', "X-Revision": str(revision)}
    return Response(out.getvalue(), media_type=EXPORT_TYPES[export], headers=headers)


@router.post(
    "/sessions/{session_id}/refine",
    status_code=202,
    response_model=JobInfoModel,
    responses={**REFINE_ERRORS, **JOB_ERRORS},
)
def refine(session_id: str, body: RefineRequest, services: ServicesDep, user: CurrentUser) -> JobInfoModel:
    """Queue pointwise maps both ways for the session's curves as they are now (a job of yours; reading the
    session is enough). The finished job links ``map_target_to_source.txt`` (line j: source vertex for target
    vertex j, file ids), the other direction, the same maps as ``.npy``, both functional maps and a textured
    target OBJ. 429 at your concurrent-jobs quota, 413 when your stored bytes are at the byte quota."""
    record = session_for(services, user, session_id, "read")
    params = converter_params(services, body, (record.source, record.target), f"session {session_id}")
    if not record.curves:
        raise Conflict(f"session {session_id} has no curves yet; add at least one before refining")
    with services.quotas.admit(user, "jobs") as charge:
        info = submit_refine(services, record, body.converter, params, user.name)
        charge(info.id)
    return job_model(info)


@router.get("/sessions/{session_id}/refinements", response_model=list[JobInfoModel], responses=ERRORS)
def list_refinements(session_id: str, services: ServicesDep, user: CurrentUser) -> list[JobInfoModel]:
    """The refinement jobs run from the session that you may see (yours, and others' finished ones), oldest first.
    A finished job's ``result.revision`` is the session revision its maps were computed from: once the session's
    revision is past it, its maps are stale."""
    session_for(services, user, session_id, "read")
    visible = []
    for job_id in services.records.jobs(session_id):
        with contextlib.suppress(CurvefmError):  # not yours and not finished, or forgotten
            visible.append(job_model(job_for(services, user, job_id)))
    return visible


def converter_params(services: Services, body: RefineRequest, shapes: tuple[str, ...], what: str) -> dict:
    """The converter's canonical parameters, checked against the shapes it will run on: a basis the shapes cannot
    have is a bad request now, not a failed job later."""
    plugin = require_plugin("converter", body.converter)
    parsed = plugin.parse_params(body.params)
    size = plugin.basis_size(parsed)
    if size:
        smallest = min(services.live.mesh(s).n_vertices for s in shapes)
        check_k(size, smallest, f"the smallest shape of {what}")
        services.sessions.limits.check("max_k", size, f"a basis of {size} functions for '{body.converter}'")
    return parsed.model_dump()


def discard_job(services: Services, job_id: str) -> None:
    """Cancel the job if it still runs and delete its result files."""
    with contextlib.suppress(CurvefmError):  # it ended already, or the queue forgot it
        services.queue.cancel(job_id)
    shutil.rmtree(results_dir(services, job_id), ignore_errors=True)


def _parse_ids(text: str | None) -> list[int] | None:
    return [int(part) for part in text.split(",")] if text else None
