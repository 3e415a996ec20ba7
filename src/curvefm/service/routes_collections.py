"""``/collections``: a template with its curves and many members (each a session the collection owns), batch
runs of refinement jobs over the members, a run's maps as one archive, member-to-member maps through the template.
Who may do which: their roles in the collection, or its lab-wide sharing (:mod:`curvefm.service.permissions`);
``/collections/{id}/roles`` grants the roles."""

from __future__ import annotations

import io
from collections import Counter
from itertools import chain, repeat
from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, File, Path, Query, Response, UploadFile
from starlette.convertors import Convertor, register_url_convertor

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
from curvefm.errors import Conflict, Forbidden, InvalidInput, LimitExceeded, NotFound, shown
from curvefm.morphometrics import (
    COLLECTION_EXPORTS,
    DEFAULT_SEMILANDMARKS,
    MAX_SEMILANDMARKS,
    Configuration,
    MemberShape,
    live_mapped,
    missing_curves,
    project_configuration,
    run_mapped,
    template_pseudo,
)
from curvefm.records.collections import ReviewState
from curvefm.records.common import MAX_OFFSET, MAX_PAGE
from curvefm.service.agreement import archive_agreement
from curvefm.service.auth import AUTHENTICATED, CurrentUser
from curvefm.service.deps import (
    JOB_ERRORS,
    Services,
    ServicesDep,
    job_admission,
    job_view,
    submit_basis,
    submit_refine,
    viewer,
)
from curvefm.service.errors import error_responses
from curvefm.service.filenames import attachment
from curvefm.service.models import (
    AnnotatorProgress,
    AnswerRequest,
    AssigneeRequest,
    Assignments,
    CollectionChange,
    CollectionSummary,
    CollectionView,
    ComposedMaps,
    CurveEdit,
    MemberMapsResponse,
    MemberProgress,
    MembersRequest,
    RoleGrant,
    RoleRequest,
    RunRequest,
    SpreadRequest,
    WorkItem,
)
from curvefm.service.openapi import SchemaRoute
from curvefm.service.owned import COLLECTIONS, LIMIT_HELP, OFFSET_HELP, TOTAL_HEADER, TOTAL_SCHEMA, discard_job, paged
from curvefm.service.permissions import (
    REFUSALS,
    annotator_named,
    capabilities,
    check_collection,
    collection_for,
    refuse_locked,
    session_for,
)
from curvefm.service.routes_reviews import review_view
from curvefm.service.routes_sessions import IfMatch, converter_params, expected_revision
from curvefm.service.routes_shapes import store_upload
from curvefm.session import BasisNeed, SessionRecord, basis_available
from curvefm.webhooks import WebhookEvent

router = APIRouter(
    tags=["collections"],
    route_class=SchemaRoute,
    dependencies=AUTHENTICATED,
    responses=error_responses(401, 403, 503, 507),
)
ERRORS = error_responses(400, 404, 409, 413, 422)
RUN_ERRORS = {
    **error_responses(
        400, 404, 409, 413, 422, 429, described={400: "the converter's parameters contradict each other"}
    ),
    **JOB_ERRORS,
}
ARCHIVE_TYPES = {"npz": "application/x-npz", "zip": "application/zip"}


class MemberIdConvertor(Convertor[str]):
    """A member id in a path: any segment but ``upload``, so that ``.../members/upload`` is no member's path (its
    ``Allow`` names POST alone)."""

    regex = "(?!upload$)[^/]+"

    def convert(self, value: str) -> str:
        return value

    def to_string(self, value: str) -> str:
        return value


register_url_convertor("member", MemberIdConvertor())


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
    members = len(body.members or []) + bool(body.from_session)
    with services.quotas.admit(user, "sessions", count=members) as conn:  # members are sessions of yours
        record = services.collections.create(body, owner=user.name, conn=conn)
    _queue_bases(services, record, user)
    services.audit.record(user.name, "collection.create", record.id, {"members": len(record.members)})
    return _view(services, record.id, user)


@router.get(
    "/collections",
    response_model=list[CollectionSummary],
    responses={200: {"headers": {TOTAL_HEADER: TOTAL_SCHEMA}}, **error_responses(422)},
)
def list_collections(
    response: Response,
    services: ServicesDep,
    user: CurrentUser,
    limit: Annotated[int | None, Query(ge=1, le=MAX_PAGE, description=LIMIT_HELP)] = None,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET, description=OFFSET_HELP)] = 0,
) -> list[CollectionSummary]:
    """The collections you may see (yours, those shared with the lab, and for admins all), the most recently
    changed first: ``limit`` of them from ``offset`` (without ``limit``: all from ``offset``). The
    ``X-Total-Count`` header says how many there are in all. Filtered, counted and sliced by the database."""
    records = services.collections.records
    rows, total = paged(lambda n, at: records.page(viewer(user), limit=n, offset=at), limit, offset)
    response.headers[TOTAL_HEADER] = str(total)
    return [CollectionSummary(**{k: getattr(r, k) for k in CollectionSummary.model_fields}) for r in rows]


@router.get("/collections/{collection_id}", response_model=CollectionView, responses=ERRORS)
def get_collection(collection_id: str, services: ServicesDep, user: CurrentUser) -> CollectionView:
    """The collection, and per member: its shape and session, its basis (ready or the job's state), the template
    curves answered on it, and its job in the newest run that ran it."""
    collection_for(services, user, collection_id, "read")
    return _view(services, collection_id, user)


@router.patch("/collections/{collection_id}", response_model=CollectionRecord, responses=ERRORS)
def change_collection(
    collection_id: str, body: CollectionChange, services: ServicesDep, user: CurrentUser
) -> CollectionRecord:
    """Share the collection (and its member sessions) with the lab, or make it private: its owner, a manager or an
    admin. The sharing is a lab-wide default: each user may do what their role or the sharing allows, whichever
    allows more."""
    return COLLECTIONS.share(services, user, collection_id, body.sharing)


@router.delete("/collections/{collection_id}", status_code=204, responses=ERRORS)
def delete_collection(collection_id: str, services: ServicesDep, user: CurrentUser) -> Response:
    """Delete the collection, its member sessions and their refinement results: an owner or an admin."""
    COLLECTIONS.delete(services, user, collection_id)
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


@router.delete("/collections/{collection_id}/members/{member_id:member}", status_code=204, responses=ERRORS)
def remove_member(
    collection_id: str,
    member_id: Annotated[str, Path(description="m1, m2, ...")],
    services: ServicesDep,
    user: CurrentUser,
) -> Response:
    """Remove a member: its session, its curves and the result files of its refinement jobs go with it (running
    ones are canceled first), and it leaves the collection's runs. Whoever may add members (an owner, a manager,
    an admin, or every user when the collection is shared editable)."""
    collection_for(services, user, collection_id, "edit")
    for job_id in services.collections.remove_member(collection_id, member_id):  # (announces member.removed)
        discard_job(services, job_id)
    services.audit.record(user.name, "collection.remove_member", collection_id, {"member": member_id})
    return Response(status_code=204)


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
    files: Annotated[list[UploadFile], File(description="mesh files, one member each")] = [],  # noqa: B006 (FastAPI copies defaults)
) -> CollectionView:
    """Upload several meshes at once (as ``POST /shapes`` each) and add them as members. The members' limit and
    your sessions quota are checked before anything is stored: a refused upload stores no shape."""
    record = collection_for(services, user, collection_id, "edit")
    if not files:  # a multipart body without parts: the schema cannot ask for at least one
        raise InvalidInput("upload at least one mesh file (multipart field 'files')")
    count = len(record.members) + len(files)
    services.collections.limits.check("max_members", count, f"{count} members in collection {collection_id}")
    with services.quotas.admit(user, "sessions", count=len(files)):
        pass  # checked again when the members are added
    shapes = [store_upload(services, user, file)[0] for file in files]
    return _with_members(services, user, collection_id, shapes)


def _with_members(services: Services, user: User, collection_id: str, shapes: list[str]) -> CollectionView:
    """Add the stored shapes as members, queue their basis jobs, and return the collection's view."""
    before = {m.id for m in services.collections.record(collection_id).members}
    with services.quotas.admit(user, "sessions", count=len(shapes)) as conn:  # members are sessions of yours
        services.collections.add_members(collection_id, shapes, conn=conn)
    record = services.collections.record(collection_id)
    _queue_bases(services, record, user)
    for member in (m for m in record.members if m.id not in before):
        data = {"member": member.id, "shape": member.shape, "session": member.session}
        services.webhooks.notify(collection_id, WebhookEvent.MEMBER_ADDED, data)
    return _view(services, collection_id, user)


@router.post(
    "/collections/{collection_id}/members/{member_id}/curves",
    status_code=201,
    response_model=CurveEdit,
    responses=ERRORS,
)
def answer_template_curve(
    collection_id: str,
    member_id: str,
    body: AnswerRequest,
    services: ServicesDep,
    user: CurrentUser,
    if_match: IfMatch = None,
    annotator: Annotated[
        str | None,
        Query(max_length=64, description="answer in this annotator's further annotation of the member instead"),
    ] = None,
) -> CurveEdit:
    """Answer a template curve on a member: ``target`` (clicked on the member) becomes a curve of the member's
    session whose source is the template curve's path; its maps update as in a session. Answering a template
    curve again replaces the earlier answer. Extra curves (answering no template curve) go through
    ``POST /sessions/{session}/curves``; 409 while the member's basis is not ready, or while it is submitted or
    accepted in review. ``If-Match`` names the member session's revision the answer is based on, as for a
    session's edits. ``annotator``: the further annotation that annotator makes of the member (its annotator, a
    manager, an owner or an admin)."""
    if annotator is None:
        check_collection(services, user, collection_id, "answer", member_id)
        session_id = services.collections.record(collection_id).member(member_id).session
        refuse_locked(services, session_id)
    else:
        session_id = _further_annotation(services, user, collection_id, member_id, annotator)
    options = body.model_dump(exclude={"template_curve", "target"})
    watched = services.webhooks.subscribed(collection_id, WebhookEvent.MEMBER_COMPLETED)
    was_done = watched and _member_done(services, collection_id, member_id)[0]
    curve, summary = services.collections.answer(
        collection_id, member_id, body.template_curve, body.target, expected_revision(if_match), session_id, **options
    )
    if watched and not was_done:
        done, session_id = _member_done(services, collection_id, member_id)
        if done:
            data = {"member": member_id, "session": session_id, "revision": summary.revision}
            services.webhooks.notify(collection_id, WebhookEvent.MEMBER_COMPLETED, data)
    return CurveEdit(curve=curve, map=summary)


def _member_done(services: Services, collection_id: str, member_id: str) -> tuple[bool, str]:
    """Whether every template curve of the collection is answered on the member, and the member's session."""
    record = services.collections.record(collection_id)
    session = services.sessions.record(record.member(member_id).session)
    return _progress(record, member_id, session, None, "").done, session.id


def _further_annotation(services: Services, user: User, collection_id: str, member_id: str, annotator: str) -> str:
    """The session of ``annotator``'s further annotation of the member, when ``user`` may answer in it (404: no
    such annotation)."""
    held = check_collection(services, user, collection_id, "answer")
    annotations = services.collections.records.annotations(collection_id)
    mine = [a for a in annotations if a.member_id == member_id and a.further and a.user == annotator]
    if not mine:
        services.collections.record(collection_id).member(member_id)  # an unknown member is named as such
        raise NotFound(f"'{shown(annotator)}' makes no further annotation of member {member_id}")
    if "answer_any" not in held and annotator != user.name:
        raise Forbidden(f"collection {collection_id}: {REFUSALS['answer_any']}")
    return mine[0].session_id


@router.get("/collections/{collection_id}/roles", response_model=list[RoleGrant], responses=ERRORS)
def list_roles(collection_id: str, services: ServicesDep, user: CurrentUser) -> list[RoleGrant]:
    """Who holds which role in the collection: its creator (an owner by making it) first, then the granted roles
    by role and name. Whoever may read the collection."""
    record = collection_for(services, user, collection_id, "read")
    grants = [RoleGrant(**vars(g)) for g in services.collections.records.grants(collection_id)]
    creator = services.users.get(record.owner)
    if creator is None:  # removed: the collection keeps its granted owners and managers
        return grants
    made = RoleGrant(user=creator.name, user_id=creator.id, role="owner", granted_by=None, granted_at=record.created_at)
    return [made, *grants]


@router.put("/collections/{collection_id}/roles/{user_name}", response_model=RoleGrant, responses=ERRORS)
def grant_role(
    collection_id: str, user_name: str, body: RoleRequest, services: ServicesDep, user: CurrentUser
) -> RoleGrant:
    """Give a user a role in the collection (replacing the one they held): an owner, a manager or an admin; the
    owner role (given, or taken by replacing it) an owner or an admin alone. Audited as ``collection.grant``."""
    target, previous = _grantee(services, user, collection_id, user_name, body.role)
    services.collections.records.grant(collection_id, target.id, body.role, user.id)
    detail = {"user": target.name, "user_id": target.id, "role": body.role, "previous": previous}
    services.audit.record(user.name, "collection.grant", collection_id, detail)
    (granted,) = [g for g in services.collections.records.grants(collection_id) if g.user_id == target.id]
    return RoleGrant(**vars(granted))


@router.delete("/collections/{collection_id}/roles/{user_name}", status_code=204, responses=ERRORS)
def revoke_role(collection_id: str, user_name: str, services: ServicesDep, user: CurrentUser) -> Response:
    """Take a user's role in the collection away (they keep what its sharing allows every user): as granting;
    404 for a user holding none. Audited as ``collection.revoke``."""
    target, previous = _grantee(services, user, collection_id, user_name, None)
    if previous is None:
        raise NotFound(f"user '{target.name}' holds no role in collection {collection_id}")
    services.collections.records.revoke(collection_id, target.id)
    detail = {"user": target.name, "user_id": target.id, "role": previous}
    services.audit.record(user.name, "collection.revoke", collection_id, detail)
    return Response(status_code=204)


def _grantee(
    services: Services, user: User, collection_id: str, user_name: str, role: str | None
) -> tuple[User, str | None]:
    """The user whose role changes and the role they hold, once ``user`` may change it to ``role`` (None: take it
    away): 404 for a user that does not exist, 403 for owners' grants unless ``user`` is an owner (the records
    refuse to change the creator's role)."""
    held = check_collection(services, user, collection_id, "manage")
    target = services.users.get(user_name)
    if target is None:
        raise NotFound(f"no user named '{shown(user_name)}'")
    grants = services.collections.records.grants(collection_id)
    previous = next((g.role for g in grants if g.user_id == target.id), None)
    if "owner" in (role, previous) and "own" not in held:
        raise Forbidden(f"collection {collection_id}: {REFUSALS['own']}; ask one of its owners")
    return target, previous


@router.put(
    "/collections/{collection_id}/members/{member_id}/assignee", response_model=MemberProgress, responses=ERRORS
)
def assign_member(
    collection_id: str, member_id: str, body: AssigneeRequest, services: ServicesDep, user: CurrentUser
) -> MemberProgress:
    """Assign a member to an annotator (a user who may answer in the collection), or to no one (``null``): an
    owner, a manager or an admin. Once any member is assigned, annotators answer only the members assigned to
    them. Audited as ``collection.assign``."""
    check_collection(services, user, collection_id, "manage")
    assignee = annotator_named(services, collection_id, body.user) if body.user else None
    services.collections.records.assign(collection_id, {member_id: assignee.id if assignee else None})
    services.audit.record(user.name, "collection.assign", collection_id, {"members": [member_id], "user": body.user})
    (progress,) = [p for p in _assignments(services, collection_id).members if p.member == member_id]
    return progress


@router.post("/collections/{collection_id}/assign", response_model=Assignments, responses=ERRORS)
def spread_members(collection_id: str, body: SpreadRequest, services: ServicesDep, user: CurrentUser) -> Assignments:
    """Spread members evenly over ``annotators``: each member (``members``, by default those assigned to no one,
    in order) goes to the annotator with the fewest members assigned so far (ties: the first named). As
    ``PUT .../assignee``: an owner, a manager or an admin; audited as ``collection.assign``."""
    check_collection(services, user, collection_id, "manage")
    annotators = [annotator_named(services, collection_id, name) for name in dict.fromkeys(body.annotators)]
    record, records = services.collections.record(collection_id), services.collections.records
    assigned = records.assignees(collection_id)
    if body.members:
        members = [record.member(member_id).id for member_id in dict.fromkeys(body.members)]
    else:
        members = [m.id for m in record.members if m.id not in assigned]
    load = Counter(user_id for member_id, (user_id, _) in assigned.items() if member_id not in members)
    plan: dict[str, int | None] = {}
    for member_id in members:
        chosen = min(annotators, key=lambda annotator: load[annotator.id])
        plan[member_id], load[chosen.id] = chosen.id, load[chosen.id] + 1
    records.assign(collection_id, plan)
    detail = {"members": members, "annotators": [a.name for a in annotators]}
    services.audit.record(user.name, "collection.assign", collection_id, detail)
    return _assignments(services, collection_id)


@router.get("/collections/{collection_id}/assignments", response_model=Assignments, responses=ERRORS)
def get_assignments(collection_id: str, services: ServicesDep, user: CurrentUser) -> Assignments:
    """Progress per member (its annotator, template curves answered) and per annotator (members assigned, done,
    and the next one to do). Whoever may read the collection."""
    check_collection(services, user, collection_id, "read")
    return _assignments(services, collection_id)


@router.get("/me/work", response_model=list[WorkItem])
def my_work(services: ServicesDep, user: CurrentUser) -> list[WorkItem]:
    """The members assigned to you in every collection you may still read, and the further annotations of members
    asked of you (``further``: answer them in their ``session``, not reviewed): those not done first (the first is
    what is next), the most recently changed collection first, members in order."""
    items, states = [], ReviewStates(services)
    for work in services.collections.records.work(user.id):
        if "read" not in capabilities(user, services.collections.records.standing(work.collection_id, viewer(user))):
            continue
        session = services.sessions.record(work.session_id)
        record = services.collections.record(work.collection_id)
        names = services.shapes.names([work.shape])
        shape_name = names.get(work.shape) or work.shape[:12]
        review: ReviewState = "open" if work.further else states.of(record.id, work.member_id)
        progress = _progress(record, work.member_id, session, user.name, shape_name, review)
        item = WorkItem(
            collection=record.id, collection_name=record.name, further=work.further, **progress.model_dump()
        )
        items.append(item)
    return sorted(items, key=lambda item: item.done)


def _assignments(services: Services, collection_id: str) -> Assignments:
    record = services.collections.record(collection_id)
    assigned = services.collections.records.assignees(collection_id)
    names = services.shapes.names([m.shape for m in record.members])
    states = ReviewStates(services)
    members = [
        _progress(
            record,
            m.id,
            services.sessions.record(m.session),
            assigned[m.id][1] if m.id in assigned else None,
            names.get(m.shape) or m.shape[:12],
            states.of(collection_id, m.id),
        )
        for m in record.members
    ]
    by_user: dict[str, list[MemberProgress]] = {}
    for progress in members:
        if progress.assignee is not None:
            by_user.setdefault(progress.assignee, []).append(progress)
    annotators = [
        AnnotatorProgress(
            user=name,
            assigned=len(mine),
            done=sum(p.done for p in mine),
            next=next((p.member for p in mine if not p.done), None),
        )
        for name, mine in sorted(by_user.items())
    ]
    return Assignments(members=members, annotators=annotators)


class ReviewStates:
    """Members' review states, read once per collection asked about."""

    def __init__(self, services: Services):
        self.records = services.collections.records
        self.read: dict[str, dict[str, ReviewState]] = {}

    def of(self, collection_id: str, member_id: str) -> ReviewState:
        if collection_id not in self.read:
            self.read[collection_id] = {m: r.state for m, r in self.records.reviews(collection_id).items()}
        return self.read[collection_id].get(member_id, "open")


def _progress(
    record: CollectionRecord,
    member_id: str,
    session: SessionRecord,
    assignee: str | None,
    shape_name: str,
    review: ReviewState = "open",
) -> MemberProgress:
    templates = {c.id for c in record.curves}
    answered = len({c.spec.template_curve for c in session.curves} & templates)
    return MemberProgress(
        member=member_id,
        shape_name=shape_name,
        session=session.id,
        assignee=assignee,
        curves_done=answered,
        curves_total=len(templates),
        done=bool(templates) and answered == len(templates),
        review=review,
    )


@router.post("/collections/{collection_id}/runs", status_code=202, response_model=RunStatus, responses=RUN_ERRORS)
def start_run(collection_id: str, body: RunRequest, services: ServicesDep, user: CurrentUser) -> RunStatus:
    """Refine every member (or ``members``; with ``only_ready``, those of them that have curves; with
    ``only_accepted``, those of them a reviewer accepted: 409 when none is) as one job each
    on the workers, with one converter and parameters (as ``POST /sessions/{id}/refine``); 409 names the members
    without curves unless ``only_ready``. A run is admitted once by your concurrent-jobs quota (429 at it); its
    jobs then count towards it until they end. Members left out keep their previous run's jobs. A run is recorded
    in the collection, so it needs the right to edit it (a read-only sharer refines a member's session instead)."""
    record = collection_for(services, user, collection_id, "edit")
    shapes = (record.template, *(m.shape for m in record.members))
    params = converter_params(services, body, shapes, f"collection {collection_id}")
    admissions = chain([job_admission(services, user)], repeat(None))  # the run's first job admits it

    def submit(session) -> str:
        return submit_refine(services, session, body.converter, params, user.name, next(admissions)).id

    members = _accepted(services, record, body.members) if body.only_accepted else body.members
    run = services.collections.start_run(collection_id, body.converter, params, submit, members, body.only_ready)
    services.webhooks.run_recorded(collection_id, run.id)
    services.audit.record(user.name, "collection.run", collection_id, {"run": run.id, "jobs": len(run.members)})
    return run_status(run, lambda job_id: job_view(services, job_id))


def _accepted(services: Services, record: CollectionRecord, members: list[str] | None) -> list[str]:
    """The members (of ``members``, by default all) a reviewer accepted; 409 when none is."""
    chosen = [record.member(m).id for m in dict.fromkeys(members)] if members else [m.id for m in record.members]
    states = ReviewStates(services)
    accepted = [m for m in chosen if states.of(record.id, m) == "accepted"]
    if not accepted:
        raise Conflict(f"no member of collection {record.id} asked for is accepted yet; a reviewer accepts them")
    return accepted


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
    the same as ``<member>/<name>.txt`` files. When the collection has double annotations, ``summary.json``
    holds the agreement report too (``agreement``, as ``GET .../agreement``; 409 while a basis it needs is not
    ready), and so it does with the check members' accuracy (``agreement.checks``) when the collection has check
    members and the caller manages it (no one else learns which members are checks). 409 names the members still
    pending or failed."""
    manages = "manage" in check_collection(services, user, collection_id, "read")
    record = services.collections.record(collection_id)
    run, maps = _maps(services, record, run_id)
    out = io.BytesIO()
    settings = services.settings
    agreement = archive_agreement(
        services.collections, record, settings.agreement_points, settings.agreement_threshold, manages
    )
    (write_npz if kind == "npz" else write_zip)(out, maps, archive_summary(record, run, maps, agreement))
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


CollectionExport = Literal["landmarks.tps", "morphologika.txt", "curveslide.csv", "pseudo_landmarks.csv"]


@router.get(
    "/collections/{collection_id}/exports/{export}",
    response_class=Response,
    responses={
        200: {"content": {media: {"schema": {"type": "string"}} for media, _ in COLLECTION_EXPORTS.values()}},
        **error_responses(400, 404, 409, 413, 422, described={400: "pseudo_landmarks.csv without pseudo-landmarks"}),
    },
)
def get_collection_export(
    collection_id: str,
    export: CollectionExport,
    services: ServicesDep,
    user: CurrentUser,
    semilandmarks: Annotated[
        int, Query(ge=0, le=MAX_SEMILANDMARKS, description="semilandmarks per template curve, between its ends")
    ] = DEFAULT_SEMILANDMARKS,
    pseudo: Annotated[
        int,
        Query(
            ge=0,
            description="pseudo-landmarks: template vertices spread by farthest-point sampling, each carried to every "
            "member by the member's map; 413 past CURVEFM_MAX_PSEUDO_LANDMARKS",
        ),
    ] = 0,
    run: Annotated[
        str | None,
        Query(
            max_length=16,
            description="a finished run: its members, each with the curves its job refined and its pointwise map "
            "(map_template_to_member), instead of every member's live session",
        ),
    ] = None,
    complete_only: Annotated[
        bool, Query(description="leave out the members that do not answer every template curve (else 409)")
    ] = False,
    template: Annotated[bool, Query(description="the template as the first specimen")] = False,
) -> Response:
    """The collection's correspondences as landmark files with one specimen per member (docs: collections,
    formats): every template curve's endpoints, ``semilandmarks`` points along each at equal arc-length steps and
    ``pseudo`` pseudo-landmarks, in the same order on every member. ``landmarks.tps`` (``LM3=``, ``ID=`` the
    member and its shape), ``morphologika.txt``, ``curveslide.csv`` (geomorph's sliders, 1-based) and
    ``pseudo_landmarks.csv`` (per member and pseudo-landmark: the template vertex, the member vertex, file ids, and
    its position). Whoever may read the collection; 409 names the members that lack template curves."""
    record = collection_for(services, user, collection_id, "read")
    limit = services.settings.max_pseudo_landmarks
    if pseudo > limit:
        raise LimitExceeded("max_pseudo_landmarks", limit, f"{pseudo} pseudo-landmarks")
    if export == "pseudo_landmarks.csv" and not pseudo:
        raise InvalidInput("pseudo_landmarks.csv lists the pseudo-landmarks: ask for some (?pseudo=N)")
    configuration = _project(services, record, semilandmarks, pseudo, run, complete_only, template)
    media, write = COLLECTION_EXPORTS[export]
    filename = f"collection_{collection_id}_{run or 'live'}_{export}"
    return Response(write(configuration), media_type=media, headers=attachment(filename))


def _project(
    services: Services,
    record: CollectionRecord,
    semilandmarks: int,
    pseudo: int,
    run_id: str | None,
    complete_only: bool,
    with_template: bool,
) -> Configuration:
    """The configuration of the collection's members (live) or of a run's (its jobs' snapshots and maps)."""
    template_curves = [curve.id for curve in record.curves]
    if run_id is None:
        members = record.members
        sessions = {m.id: services.sessions.record(m.session) for m in members}
    else:
        members = [record.member(member_id) for member_id in record.run(run_id).members]
        maps = {m.member: m for m in _maps(services, record, run_id, [m.id for m in members])[1]}
        sessions = {m.id: _refined_session(services, maps[m.id].job) for m in members}
    incomplete = {m.id: missing_curves(sessions[m.id], template_curves) for m in members}
    incomplete = {member_id: curves for member_id, curves in incomplete.items() if curves}
    if incomplete and not complete_only:
        named = "; ".join(f"{member_id} lacks {', '.join(curves)}" for member_id, curves in incomplete.items())
        raise Conflict(
            f"members of collection {record.id} do not answer every template curve ({named}); answer them, or "
            "export the members that do (complete_only=true)"
        )
    members = [m for m in members if m.id not in incomplete]
    if not members:
        raise Conflict(f"no member of collection {record.id} answers every template curve yet")
    names = services.shapes.names([record.template, *(m.shape for m in members)])
    template_mesh = services.live.mesh(record.template, "template")
    on_template = template_pseudo(template_mesh, pseudo) if pseudo else None
    shapes = []
    for member in members:
        mesh = services.live.mesh(member.shape, "member")
        mapped = None
        if on_template is not None and run_id is None:
            mapped = live_mapped(services.sessions, member.session, on_template)
        elif on_template is not None:
            mapped = run_mapped(template_mesh, mesh, maps[member.id].arrays["map_template_to_member"], on_template)
        name = f"{member.id} {names.get(member.shape) or member.shape[:12]}"
        shapes.append(MemberShape(name, sessions[member.id], mesh, mapped))
    template_name = names.get(record.template) or record.template[:12]
    return project_configuration(
        template_mesh, template_name, template_curves, shapes, semilandmarks, on_template, with_template
    )


def _refined_session(services: Services, job_id: str) -> SessionRecord:
    """The member session as its refinement job refined it (the snapshot it was given)."""
    stored = services.queue.records.load(job_id)
    if stored is None:
        raise Conflict(f"job {job_id} has no stored session snapshot; run the members again")
    return SessionRecord.model_validate(stored.kwargs["session"])


def _maps(services: Services, record: CollectionRecord, run_id: str, only: list[str] | None = None):
    run = record.run(run_id)
    for member_id in only or ():
        record.member(member_id)  # an unknown member is a 404, not a pending one
        if member_id not in run.members:
            raise NotFound(f"member {member_id} is not in run {run_id}; run it (POST .../runs with members)")
    results = services.store.root / "results"
    return run, run_maps(record, run, lambda job_id: job_view(services, job_id), results, only)


def _view(services: Services, collection_id: str, user: User) -> CollectionView:
    """The collection with its members' progress, and what ``user`` may do in it."""
    record = services.collections.record(collection_id)
    names = services.shapes.names([m.shape for m in record.members])
    members = [
        member_status(
            record,
            m,
            services.sessions.record(m.session),
            _basis_state(services, record, m.shape, m.basis_job),
            lambda job_id: job_view(services, job_id),
            names.get(m.shape) or m.shape[:12],
        )
        for m in record.members
    ]
    may = capabilities(user, services.collections.records.standing(collection_id, viewer(user)))
    assignees = {member: name for member, (_, name) in services.collections.records.assignees(collection_id).items()}
    reviews = {member: review_view(r) for member, r in services.collections.records.reviews(collection_id).items()}
    return CollectionView(collection=record, members=members, may=sorted(may), assignees=assignees, reviews=reviews)


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
