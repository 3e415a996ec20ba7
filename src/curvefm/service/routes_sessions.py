"""``/sessions``: a shape pair, its curves, the maps both ways, transfers and refinement jobs; sharing and
deleting. Who may do which: :mod:`curvefm.service.permissions`."""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass
from functools import partial
from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, Depends, File, Header, Query, Response, UploadFile
from pydantic import StringConstraints
from pydantic.json_schema import SkipJsonSchema
from starlette.concurrency import run_in_threadpool

from curvefm.errors import Conflict, CurvefmError, InvalidInput, NotFound
from curvefm.geometry import save_textured_zip
from curvefm.matching import save_maps_mat
from curvefm.morphometrics import (
    DEFAULT_SEMILANDMARKS,
    EXPORTS,
    MAX_PSEUDO_LANDMARKS,
    MAX_SEMILANDMARKS,
    Configuration,
    Seeding,
    Tolerance,
    check_limits,
    live_configuration,
    pair_markups,
    read_markups,
    refined_configuration,
    seed_curves,
)
from curvefm.records.common import MAX_OFFSET, MAX_PAGE, Page
from curvefm.records.sessions import SessionSummary as RecordSummary
from curvefm.service.auth import AUTHENTICATED, CurrentUser
from curvefm.service.carried import CarriedFunction, CarriedKind, carried
from curvefm.service.deps import (
    JOB_ERRORS,
    Services,
    ServicesDep,
    job_admission,
    job_model,
    refined_session,
    results_dir,
    submit_refine,
    viewer,
)
from curvefm.service.errors import error_responses, require_plugin
from curvefm.service.filenames import LIVE, attachment, download_name
from curvefm.service.models import (
    CurveEdit,
    JobInfoModel,
    MapResponse,
    MarkupsImported,
    RefineRequest,
    SessionChange,
    SessionSummary,
)
from curvefm.service.openapi import SchemaRoute
from curvefm.service.owned import LIMIT_HELP, OFFSET_HELP, SESSIONS, TOTAL_HEADER, TOTAL_SCHEMA, paged
from curvefm.service.permissions import Need, job_for, session_for
from curvefm.session import (
    NAME_LENGTH,
    CurveSpec,
    CurveSuggestion,
    SessionCreate,
    SessionRecord,
    SolveStatement,
    StatedMaps,
    TransferFunction,
    check_revision,
)
from curvefm.spectral import check_k
from curvefm.workers.interface import ENDED_STATES, JobInfo

router = APIRouter(  # 503: a session busy for longer than CURVEFM_SESSION_LOCK_TIMEOUT
    tags=["sessions"],
    route_class=SchemaRoute,
    dependencies=AUTHENTICATED,
    responses=error_responses(401, 403, 503, 507),
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
SUGGESTION_ERRORS = error_responses(
    400, 404, 409, 413, 422, described={400: "moved ends given on one shape only (source and target go together)"}
)

MAX_CURVES_POSITION = 10**6  # beyond any list (max_curves bounds it): a position past the end means last
ETAG_SCHEMA = {"description": 'the session\'s revision, quoted ("5")', "schema": {"type": "string"}}
REVISION_TAG = Annotated[str, StringConstraints(pattern=r'^(W/)?"?[0-9]{1,9}"?$')]
IfMatch = Annotated[
    REVISION_TAG | SkipJsonSchema[None],  # absent or a revision: never null
    Header(
        alias="If-Match",
        description="the session revision this edit is based on (the web UI always sends it): 409, with the "
        "current revision in the body, when the session is at another (someone else changed it since you read "
        "it); without it the edit applies to whatever the session is now",
    ),
]


def expected_revision(if_match: str | None) -> int | None:
    """The revision an ``If-Match`` header names (``5``, ``"5"`` or ``W/"5"``, as the session's ``ETag``)."""
    return None if if_match is None else int(if_match.removeprefix("W/").strip('"'))


@router.post("/sessions", status_code=201, response_model=SessionRecord, responses=QUOTA_ERRORS)
def create_session(body: SessionCreate, services: ServicesDep, user: CurrentUser) -> SessionRecord:
    """Create a session of yours on two shapes (private unless ``sharing`` says otherwise). Both need a basis
    with at least ``k`` functions already (409 names the missing ones and how to request them). 429 at your
    sessions quota."""
    with services.quotas.admit(user, "sessions") as conn:  # counted and stored in one transaction
        record = services.sessions.create(body, owner=user.name, conn=conn)
    services.live.prepare(record.id)
    services.audit.record(user.name, "session.create", record.id, {"sharing": record.sharing})
    return record


@router.get(
    "/sessions",
    response_model=list[SessionSummary],
    responses={200: {"headers": {TOTAL_HEADER: TOTAL_SCHEMA}}, **error_responses(422)},
)
def list_sessions(
    response: Response,
    services: ServicesDep,
    user: CurrentUser,
    limit: Annotated[int | None, Query(ge=1, le=MAX_PAGE, description=LIMIT_HELP)] = None,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET, description=OFFSET_HELP)] = 0,
    q: Annotated[
        str | None,
        Query(max_length=NAME_LENGTH, description="only sessions whose name or shape names contain this (any case)"),
    ] = None,
    in_collection: Annotated[
        bool | None,
        Query(description="false: only sessions of their own; true: only collections' member sessions; none: both"),
    ] = None,
) -> list[SessionSummary]:
    """The sessions you may see (yours, those shared with the lab, and for admins all), the most recently changed
    first: ``limit`` of them from ``offset`` (without ``limit``: all from ``offset``). ``q`` keeps those whose name
    or shape names contain it; ``in_collection=false`` leaves out the member sessions of collections (each entry's
    ``collection`` and ``member`` name them). The ``X-Total-Count`` header says how many match in all. Filtered and
    counted by the database: a page costs the same with 10,000 sessions as with 50."""

    def page(n: int, at: int) -> Page[RecordSummary]:
        return services.records.page(viewer(user), limit=n, offset=at, query=q, in_collection=in_collection)

    rows, total = paged(page, limit, offset)
    response.headers[TOTAL_HEADER] = str(total)
    return [SessionSummary(**{k: getattr(s, k) for k in SessionSummary.model_fields}) for s in rows]


@router.get(
    "/sessions/{session_id}",
    response_model=SessionRecord,
    responses={200: {"headers": {"ETag": ETAG_SCHEMA}}, **ERRORS},
)
def get_session(session_id: str, response: Response, services: ServicesDep, user: CurrentUser) -> SessionRecord:
    """The session with its curves; ``ETag`` is its revision, for the ``If-Match`` of an edit based on it."""
    record = session_for(services, user, session_id, "read")
    response.headers["ETag"] = f'"{record.revision}"'
    return record


@router.patch("/sessions/{session_id}", response_model=SessionRecord, responses=ERRORS)
def change_session(
    session_id: str, body: SessionChange, services: ServicesDep, user: CurrentUser, if_match: IfMatch = None
) -> SessionRecord:
    """Rename the session (``name``: its owner, an admin, or every user when it is shared editable), and share it
    with the lab (``read`` or ``edit``) or make it ``private`` again (``sharing``: its owner or an admin). Both
    are checked before either is changed; a body with neither changes nothing and answers the session."""
    need: Need = "manage" if body.sharing is not None else "edit" if body.name is not None else "read"
    record = session_for(services, user, session_id, need)
    check_revision(record, expected_revision(if_match))
    if body.name is not None:
        record = services.sessions.rename(session_id, body.name.strip())
        services.audit.record(user.name, "session.rename", session_id, {"name": record.name})
    if body.sharing is not None:
        record = SESSIONS.share(services, user, session_id, body.sharing)
    return record


@router.delete("/sessions/{session_id}", status_code=204, responses=ERRORS)
def delete_session(session_id: str, services: ServicesDep, user: CurrentUser) -> Response:
    """Delete the session and the result files of its refinement jobs (running ones are canceled first): its
    owner or an admin."""
    SESSIONS.delete(services, user, session_id)
    return Response(status_code=204)


FILE_IDS = r"^[0-9]{1,10}(,[0-9]{1,10})*$"  # ten digits at most: no id beyond int64 reaches numpy
RESOLUTION = Query(
    description="full: a row per target vertex; display: a row per vertex of the target as GET "
    "/shapes/{id}/mesh draws it (its display copy when it has one), as the web UI asks"
)
Carry = Annotated[
    CarriedKind | None,
    Query(
        description="also carry this source function to the target through the new map, in the answer's "
        "``carried`` (as GET /sessions/{id}/transfer gives it, compactly): a click then costs the page one request"
    ),
]


@dataclass
class CarryQuery:
    """An edit's ``?carry=`` and ``&resolution=``: what its answer carries besides the curve and the map summary."""

    carry: CarriedKind | None
    resolution: Literal["full", "display"]

    def answer(self, services: Services, session_id: str) -> CarriedFunction | None:
        if self.carry is None:
            return None
        transferred = services.sessions.transfer(session_id, self.carry, display=self.resolution == "display")
        return carried(self.carry, transferred)


async def carry_query(
    carry: Carry = None, resolution: Annotated[Literal["full", "display"], RESOLUTION] = "full"
) -> CarryQuery:
    # async: the class itself as the dependency would be called in a worker thread, a second hand-off per edit
    return CarryQuery(carry, resolution)


CarryDep = Annotated[CarryQuery, Depends(carry_query)]


# The curve edits are the hot path: async routes doing their blocking work (locks, tracing, the durable write) in
# one trip to the thread pool; a plain route would take a second trip to validate its response.
@router.post("/sessions/{session_id}/curves", status_code=201, response_model=CurveEdit, responses=ERRORS)
async def add_curve(
    session_id: str,
    body: CurveSpec,
    services: ServicesDep,
    user: CurrentUser,
    carry: CarryDep,
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
    if_match: IfMatch = None,
) -> CurveEdit:
    """Trace a curve pair (waypoints joined by the tracer, or ``explicit`` vertex paths; file ids), update
    both maps, store the session, then answer with the traced paths and the new map summary; with ``carry``, also
    the function carried through the new map (``carried``, at ``resolution``), as the web UI asks."""

    def edit() -> CurveEdit:
        read = session_for(services, user, session_id, "edit")
        expected = expected_revision(if_match)
        curve, summary = services.sessions.add_curve(session_id, body, curve_id, position, expected, read=read)
        return CurveEdit(curve=curve, map=summary, carried=carry.answer(services, session_id))

    return await run_in_threadpool(edit)


@router.put("/sessions/{session_id}/curves/{curve_id}", response_model=CurveEdit, responses=ERRORS)
async def replace_curve(
    session_id: str,
    curve_id: str,
    body: CurveSpec,
    services: ServicesDep,
    user: CurrentUser,
    carry: CarryDep,
    if_match: IfMatch = None,
) -> CurveEdit:
    """Trace the curve pair again from a new spec; answers as ``POST /sessions/{id}/curves`` does."""

    def edit() -> CurveEdit:
        read = session_for(services, user, session_id, "edit")
        expected = expected_revision(if_match)
        curve, summary = services.sessions.replace_curve(session_id, curve_id, body, expected, read=read)
        return CurveEdit(curve=curve, map=summary, carried=carry.answer(services, session_id))

    return await run_in_threadpool(edit)


@router.delete("/sessions/{session_id}/curves/{curve_id}", response_model=CurveEdit, responses=ERRORS)
async def remove_curve(
    session_id: str,
    curve_id: str,
    services: ServicesDep,
    user: CurrentUser,
    carry: CarryDep,
    if_match: IfMatch = None,
) -> CurveEdit:
    """Remove a curve and update both maps; answers with the new map summary (and ``carried``, as for an add)."""

    def edit() -> CurveEdit:
        read = session_for(services, user, session_id, "edit")
        summary = services.sessions.remove_curve(session_id, curve_id, expected_revision(if_match), read=read)
        return CurveEdit(map=summary, carried=carry.answer(services, session_id))

    return await run_in_threadpool(edit)


@router.get("/sessions/{session_id}/map", response_model=MapResponse, responses=ERRORS)
def get_map(session_id: str, services: ServicesDep, user: CurrentUser) -> MapResponse:
    """Both functional maps now, with what they are: ``solve`` gives the energy, its weights and the size they are
    handed out at, and why (a session asking k = 60 gets 50 x 50 below 20 curves)."""
    session_for(services, user, session_id, "read")
    maps = services.sessions.stated_maps(session_id)
    return MapResponse(
        revision=maps.record.revision,
        k=len(maps.C_MN),
        solve=maps.solve,
        C_source_to_target=maps.C_MN.tolist(),
        C_target_to_source=maps.C_NM.tolist(),
    )


@router.get("/sessions/{session_id}/solve", response_model=SolveStatement, responses=ERRORS)
def get_solve(session_id: str, services: ServicesDep, user: CurrentUser) -> SolveStatement:
    """What the session's maps are now (energy, weights, size) and why, without the maps: what the web UI's status
    line shows, and what every curve edit's ``map.solve`` answers."""
    session_for(services, user, session_id, "read")
    return services.sessions.solve(session_id)


def _float32_rows(headers: dict) -> dict:
    """The responses of a route answering float32 rows per target vertex, with ``headers``."""
    binary = {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}}
    return {200: {"content": binary, "headers": headers}, **ERRORS}


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
            "description": f"file id of the {role} vertex that drifts furthest clear of the curves (where to click "
            "next)",
            "schema": {"type": "string"},
        }
        for role in ("target", "source")
    },
    "X-Prior-Pending": {
        "description": "true while the landmark prior for the current curves is being computed: the figures of "
        "this revision will still change, so read again shortly; else false",
        "schema": {"type": "string", "enum": ["true", "false"]},
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
    marks where no curve constrains the maps yet: the vertex that drifts furthest on each shape among those clear
    of the curves (more than 0.1 sqrt(area) from every path vertex, or half that where the curves leave no such
    vertex; headers ``X-Worst-Target``, ``X-Worst-Source``,
    file ids, of the whole shapes) is where a new curve helps most. ``X-Score`` is the area-weighted mean drift on
    the whole target; ``X-Revision`` the session revision; ``X-Prior-Pending: true``: the maps measured will still
    improve once the landmark prior for this revision lands (measure again shortly)."""
    session_for(services, user, session_id, "read")
    quality = services.sessions.quality(session_id, display=resolution == "display")
    headers = {
        "X-Shape": f"{len(quality.drift)},1",
        "X-Revision": str(quality.revision),
        "X-Score": f"{quality.score:.6g}",
        "X-Worst-Target": str(quality.worst_target),
        "X-Worst-Source": str(quality.worst_source),
        "X-Prior-Pending": "true" if quality.prior_pending else "false",
    }
    return Response(quality.drift.astype("<f4").tobytes(), media_type="application/octet-stream", headers=headers)


ENDS = r"^[0-9]{1,9},[0-9]{1,9}$"  # nine digits: below MAX_VERTEX_ID, so a spec of them is valid


@router.get("/sessions/{session_id}/suggestion", response_model=CurveSuggestion, responses=SUGGESTION_ERRORS)
def get_suggestion(
    session_id: str,
    services: ServicesDep,
    user: CurrentUser,
    paths: Annotated[
        bool, Query(description="true: with the curve traced between the ends (path_source, path_target)")
    ] = False,
    source: Annotated[
        str | None, Query(pattern=ENDS, description="start,end on the source (file ids) as the person moved them")
    ] = None,
    target: Annotated[str | None, Query(pattern=ENDS, description="start,end on the target, likewise")] = None,
) -> CurveSuggestion:
    """The next curve to draw: its start and end on the source where the live maps are least certain (large
    round-trip drift, far along the surface from every curve and from each other), and their images on the target
    through the maps, as file ids, with the ``revision`` whose maps made it. Its ends are never one vertex on either
    shape. ``paths=true``: with the curve itself on both shapes (``path_source``, ``path_target``, file ids, start
    to end), traced by the session's tracer exactly as adding the curve would trace it. ``source`` and ``target``
    (both or neither): ends the person moved, kept as given and traced (409 when both ends are one vertex). The web
    UI draws it faintly after each edit; adding it is an ordinary ``POST .../curves`` with these ends. Read apart
    from the edit, so that no edit waits for it; ``prior_pending: true``: ask again shortly."""
    session_for(services, user, session_id, "read")
    if (source is None) != (target is None):
        raise InvalidInput("give the moved ends on both shapes (source and target) or on neither")
    ends = None if source is None or target is None else (_parse_ends(source), _parse_ends(target))
    return services.sessions.suggestion(session_id, paths=paths, ends=ends)


def _parse_ends(text: str) -> list[int]:
    return [int(part) for part in text.split(",")]


EXPORT_TYPES = {
    "maps.mat": "application/x-matlab-data",
    "target_textured.zip": "application/zip",
    "C_source_to_target.npy": "application/octet-stream",
    **{name: media for name, (media, _) in EXPORTS.items()},
}
ExportName = Literal[
    "maps.mat",
    "target_textured.zip",
    "C_source_to_target.npy",
    "source.mrk.json",
    "target.mrk.json",
    "source.fcsv",
    "target.fcsv",
    "landmarks.tps",
    "morphologika.txt",
    "curveslide.csv",
]


def _export_schema(media: str) -> dict:
    if media == "application/json":
        return {
            "type": "object",
            "description": "3D Slicer markups (schema v1.0.3)",
            "required": ["@schema", "markups"],
        }
    return {"type": "string", "format": "binary"}


@router.get(
    "/sessions/{session_id}/exports/{export}",
    response_class=Response,
    responses={
        200: {
            "content": {media: {"schema": _export_schema(media)} for media in set(EXPORT_TYPES.values())},
            "headers": {"X-Revision": TRANSFER_HEADERS["X-Revision"]},
        },
        **ERRORS,
    },
)
def get_export(
    session_id: str,
    export: ExportName,
    services: ServicesDep,
    user: CurrentUser,
    semilandmarks: Annotated[
        int,
        Query(ge=0, le=MAX_SEMILANDMARKS, description="landmark exports: semilandmarks per curve, between its ends"),
    ] = DEFAULT_SEMILANDMARKS,
    pseudo: Annotated[
        int,
        Query(
            ge=0,
            le=MAX_PSEUDO_LANDMARKS,
            description="landmark exports: pseudo-landmarks, source vertices spread by farthest-point sampling "
            "with the target vertices the live map gives them",
        ),
    ] = 0,
    refinement: Annotated[
        str | None,
        Query(
            max_length=64,
            description="landmark exports: a finished refinement job of this session; its curves and pointwise map "
            "(map_source_to_target) instead of the live ones",
        ),
    ] = None,
) -> Response:
    """The live map as a file to download, named ``<session name>_<id>_live_r<revision>_<export>``. ``maps.mat``:
    both functional maps for MATLAB (``C_source_to_target``, ``C_target_to_source``, with a ``note`` saying what
    they are and how they were solved); ``C_source_to_target.npy``: the live C for numpy; ``target_textured.zip``:
    the target with the source's texture coordinates carried by the map, as OBJ + MTL + texture image (the UI's
    checkerboard). Pointwise maps come from a refinement job, whose files include the same.

    Landmarks for geometric morphometrics (docs: formats): every curve's endpoints, ``semilandmarks`` points
    along each curve at equal arc-length steps (in the same order on both shapes) and ``pseudo`` pseudo-landmarks:
    ``source.mrk.json`` / ``target.mrk.json`` (3D Slicer markups: a ``Curve`` per curve, ``Fiducial`` landmarks,
    coordinates as the mesh file has them, stated ``LPS``), ``source.fcsv`` / ``target.fcsv``, ``landmarks.tps``
    (both shapes, ``LM3=``), ``morphologika.txt`` and ``curveslide.csv`` (geomorph's sliders, 1-based)."""
    record = session_for(services, user, session_id, "read")
    converter = LIVE
    if export in EXPORTS:
        if refinement is None:
            configuration = live_configuration(services.sessions, session_id, semilandmarks, pseudo)
        else:
            configuration, converter = _refined(services, user, session_id, refinement, semilandmarks, pseudo)
        content, revision = EXPORTS[export][1](configuration).encode(), configuration.revision
    elif refinement is not None:
        raise InvalidInput(
            f"'refinement' is for the landmark exports; {export} is the live map's (a job's files have it)"
        )
    else:
        content, revision = _map_export(services, session_id, export)
    filename = download_name(session_id, record.name, converter, revision, export)
    headers = {**attachment(filename), "X-Revision": str(revision)}
    return Response(content, media_type=EXPORT_TYPES[export], headers=headers)


def _refined(
    services: Services, user, session_id: str, job_id: str, semilandmarks: int, pseudo: int
) -> tuple[Configuration, str]:
    """The landmarks of a finished refinement of the session: its snapshot's curves, its pointwise map."""
    info = job_for(services, user, job_id)
    stored = services.queue.records.load(job_id)
    path = results_dir(services, job_id) / "p2p_source_to_target.npy"
    if refined_session(services, job_id) != session_id or info.state != "finished" or stored is None:
        raise Conflict(f"job {job_id} is not a finished refinement of session {session_id}")
    if not path.is_file():
        raise NotFound(f"job {job_id} has no pointwise map file (p2p_source_to_target.npy); refine again")
    record = SessionRecord.model_validate(stored.kwargs["session"])
    meshes = (services.live.mesh(record.source, "source"), services.live.mesh(record.target, "target"))
    configuration = refined_configuration(record, meshes, np.load(path), semilandmarks, pseudo)
    return configuration, str((info.result or {}).get("converter", "refined"))


def _map_export(services: Services, session_id: str, export: str) -> tuple[bytes, int]:
    out = io.BytesIO()
    if export == "target_textured.zip":
        services.sessions.maps(session_id)  # the final map: its landmark prior computed
        carried = services.sessions.transfer(session_id, "uv")
        uv, revision = carried.rows, carried.revision
        save_textured_zip(services.live.mesh(services.sessions.record(session_id).target), uv, out, "target_textured")
    else:
        maps = services.sessions.stated_maps(session_id)
        revision = maps.record.revision
        if export == "maps.mat":
            save_maps_mat(out, maps.C_MN, maps.C_NM, _live_about(maps))
        else:
            np.save(out, maps.C_MN)
    return out.getvalue(), revision


@router.post(
    "/sessions/{session_id}/markups",
    status_code=201,
    response_model=MarkupsImported,
    responses=error_responses(
        400,
        404,
        409,
        413,
        422,
        described={400: "a file that is not Slicer markups, curves that do not pair, or a point too far from the mesh"},
    ),
)
async def import_markups(
    session_id: str,
    services: ServicesDep,
    user: CurrentUser,
    source: Annotated[UploadFile, File(description="Slicer markups (.mrk.json or .fcsv) on the source shape")],
    target: Annotated[UploadFile, File(description="Slicer markups (.mrk.json or .fcsv) on the target shape")],
    join_landmarks: Annotated[
        bool, Query(description="also join each two consecutive paired landmarks (source file order) by a curve")
    ] = False,
    if_match: IfMatch = None,
) -> MarkupsImported:
    """Seed the session's curves from 3D Slicer markups: a ``Curve`` (or ``ClosedCurve``, ``Line``) markup of the
    source file and the target file's curve of the same name (or, when no name matches, the same place in the
    file) become a curve pair, its control points snapped to the nearest vertices as waypoints joined by the
    session's tracer; ``Fiducial`` landmarks pair by label (curves between them with ``join_landmarks``). Each
    point's snapping distance is reported; a point farther from its mesh than ``CURVEFM_MARKUP_SNAP_TOLERANCE``
    (units of sqrt(area)) refuses the whole import (400, naming the point). The curves are added one edit each,
    the first at the ``If-Match`` revision, each next at the revision the one before made."""
    files = [
        (upload.filename or side, await upload.read()) for side, upload in (("source", source), ("target", target))
    ]

    def edit() -> MarkupsImported:
        record = session_for(services, user, session_id, "edit")
        check_revision(record, expected_revision(if_match))
        meshes = (services.live.mesh(record.source, "source"), services.live.mesh(record.target, "target"))
        pairs = pair_markups(*(read_markups(data, name) for name, data in files))
        tolerance = Tolerance(services.settings.markup_snap_tolerance)
        seeding = seed_curves(pairs, meshes, tolerance, join_landmarks)
        if not seeding.curves:
            raise InvalidInput("the files hold no curve pair (and no two paired landmarks with join_landmarks)")
        check_limits(seeding, services.sessions.limits, len(record.curves))
        return _add_seeded(services, session_id, seeding, expected_revision(if_match))

    return await run_in_threadpool(edit)


def _add_seeded(services: Services, session_id: str, seeding: Seeding, revision: int | None) -> MarkupsImported:
    curves, summary = [], None
    for seeded in seeding.curves:
        curve, summary = services.sessions.add_curve(session_id, seeded.spec, expected_revision=revision)
        curves.append(curve)
        revision = summary.revision if revision is not None else None
    names = [seeded.name for seeded in seeding.curves]
    return MarkupsImported(curves=curves, names=names, map=summary, points=seeding.points, unpaired=seeding.unpaired)


def _live_about(maps: StatedMaps) -> str:
    record, solve = maps.record, maps.solve
    return (
        f"Session '{record.name or record.id}' ({record.id}) at revision {record.revision}: its live functional "
        f"maps, solved as {solve.summary} ({solve.reason})."
    )


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
    target OBJ. 429 at your concurrent-jobs quota, 413 when your stored bytes are at the byte quota or when the
    memory the job states (from both shapes' vertices) is more than any worker's budget (``CURVEFM_WORKER_MEMORY``)."""
    record = session_for(services, user, session_id, "read")
    params = converter_params(services, body, (record.source, record.target), f"session {session_id}")
    if not record.curves:
        raise Conflict(f"session {session_id} has no curves yet; add at least one before refining")
    info = submit_refine(services, record, body.converter, params, user.name, job_admission(services, user))
    return job_model(info)


@router.get(
    "/sessions/{session_id}/refinements",
    response_model=list[JobInfoModel],
    responses={200: {"headers": {TOTAL_HEADER: TOTAL_SCHEMA}}, **ERRORS},
)
def list_refinements(
    session_id: str,
    response: Response,
    services: ServicesDep,
    user: CurrentUser,
    limit: Annotated[int | None, Query(ge=1, le=MAX_PAGE, description=LIMIT_HELP)] = None,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET, description=OFFSET_HELP)] = 0,
) -> list[JobInfoModel]:
    """The refinement jobs run from the session that you may see (yours, and others' finished ones), oldest first:
    ``limit`` of them from ``offset`` (without ``limit``: all from ``offset``); ``X-Total-Count`` says how many
    there are in all. A finished job's ``result.revision`` is the session revision its maps were computed from:
    once the session's revision is past it, its maps are stale."""
    session_for(services, user, session_id, "read")
    page = partial(services.queue.records.of_session, session_id, viewer(user))
    jobs, total = paged(page, limit, offset)
    response.headers[TOTAL_HEADER] = str(total)
    return [job_model(_current(services, info)) for info in jobs]


def _current(services: Services, info: JobInfo) -> JobInfo:
    """A job that has not ended as its queue knows it now (``lost`` when the queue forgot it), else as recorded."""
    if info.state not in ENDED_STATES:
        with contextlib.suppress(CurvefmError):  # Redis does not answer, or the record expired meanwhile
            return services.queue.get(info.id)
    return info


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


def _parse_ids(text: str | None) -> list[int] | None:
    return [int(part) for part in text.split(",")] if text else None
