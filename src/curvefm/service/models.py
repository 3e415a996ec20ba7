"""Request and response models of the HTTP API (they are its OpenAPI schema at ``/docs``).

Vertex ids in requests and responses are **file** ids (0-based, as in the uploaded file), except in the
binary mesh and transfer payloads, whose rows follow the mesh's internal vertex order, or the rows of a big
shape's display copy (``file_ids`` in the mesh payload translates). The session models the API shares with the
core (``SessionCreate``, ``SessionRecord``, ``CurveSpec``, ``CurveRecord``, ``MapSummary``) are defined in
:mod:`curvefm.session`.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from curvefm.collection import CollectionRecord, MemberStatus
from curvefm.fmap import DEFAULT_K
from curvefm.morphometrics import SnappedPoint
from curvefm.records.collections import ReviewState
from curvefm.service.carried import CarriedFunction
from curvefm.session import (
    EXAMPLE_PATHS,
    NAME_LENGTH,
    SHARING_DESCRIPTION,
    CurveRecord,
    CurveWeight,
    MapSummary,
    Sharing,
    SolveStatement,
    VertexId,
)
from curvefm.workers.interface import JobState


class FieldProblem(BaseModel):
    field: str = Field(description="where in the request, e.g. body.k")
    problem: str


class ErrorBody(BaseModel):
    error: str = Field(
        description="invalid, unauthenticated, forbidden, not_found, conflict, too_large, too_many, internal, "
        "unavailable or disk_full"
    )
    detail: str = Field(description="what was wrong and what to do")
    limit: str | None = Field(
        None, description="too_large and too_many: the setting (environment variable) of the limit reached"
    )
    available: list[str] | None = Field(None, description="installed plugins of the kind asked for")
    fields: list[FieldProblem] | None = Field(None, description="each field that failed validation (422)")
    error_id: str | None = Field(None, description="internal errors (500): the id the server log files it under")
    revision: int | None = Field(
        None, description="conflict with an If-Match revision (409): the record's current revision, to reload"
    )


class AuditEvent(BaseModel):
    time: str = Field(description="UTC, ISO 8601 with milliseconds")
    user: str = Field(description="who (a user name, or 'cli' for the command line)")
    action: str = Field(description="what, e.g. session.share or user.add")
    target: str = Field(description="to what: an id or a name")
    detail: dict = Field(default_factory=dict)


class BasisInfo(BaseModel):
    plugin: str
    k: int
    params_key: str


class ShapeInfo(BaseModel):
    id: str = Field(description="content hash of the validated mesh")
    name: str = Field(description="the uploaded file's name without suffix, or the name given at upload")
    uploaded_at: float | None = Field(None, description="its first upload (UNIX seconds; none: not recorded yet)")
    n_vertices: int = Field(description="vertices used by faces (internal ids 0..n_vertices-1)")
    n_faces: int
    n_file_vertices: int = Field(description="vertices in the file; file ids are 0..n_file_vertices-1")
    has_uv: bool
    uploaders: list[str] = Field(description="who uploaded it (they, and admins, may delete it)")
    report: dict = Field(description="what validation changed or noticed")
    bases: list[BasisInfo]


class BasisRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    k: int = Field(DEFAULT_K, ge=1, description="number of basis functions")
    plugin: str = "laplace-beltrami"
    params: dict = Field(default_factory=dict, description="the basis plugin's parameters (GET /plugins)")


class JobError(BaseModel):
    kind: str = Field(
        description="invalid, not_found, conflict, too_large (also: more memory than its worker's budget), internal, "
        "disk_full, timeout (past its time limit, scaled to its meshes), killed (its process was killed, e.g. by the "
        "kernel's OOM killer, while its worker lived on), worker_lost, or lost (the queue or the service forgot the "
        "job: it restarted or lost its Redis; retry it)"
    )
    message: str = Field(description="one readable line")


class JobInfoModel(BaseModel):
    id: str
    kind: str = Field(description="basis or refine")
    state: JobState
    progress: float = Field(description="0..1")
    message: str
    result: dict | None = None
    links: dict[str, str] = Field(default_factory=dict, description="where to fetch what the job produced")
    error: JobError | None = Field(None, description="why the job failed (when it failed)")
    worker: str | None = None
    created_at: float | None = None
    started_at: float | None = None
    ended_at: float | None = None
    owner: str | None = Field(None, description="the user who started it (only they, or an admin, cancel it)")


class SessionSummary(BaseModel):
    id: str
    name: str
    owner: str
    sharing: Sharing
    source: str
    target: str
    source_name: str = Field(description="the source shape's name")
    target_name: str = Field(description="the target shape's name")
    collection: str | None = Field(description="the collection whose member this session is (none: its own)")
    member: str | None = Field(description="its member id in that collection")
    k: int
    n_curves: int
    revision: int
    created_at: float
    updated_at: float = Field(description="its last change (the list's order, newest first)")


class CurveEdit(BaseModel):
    curve: CurveRecord | None = Field(None, description="the stored curve with its traced paths (file ids)")
    map: MapSummary
    carried: CarriedFunction | None = Field(None, description="the function ?carry= asked for, through the new map")


class MarkupsImported(BaseModel):
    """What ``POST /sessions/{id}/markups`` added, and where every point of the files was snapped."""

    curves: list[CurveRecord] = Field(description="the curves added, in the files' order")
    names: list[str] = Field(description="each added curve's name in the files (the markup's name or labels)")
    map: MapSummary | None = Field(description="the maps after the last curve; null when nothing was added")
    points: list[SnappedPoint]
    unpaired: list[str] = Field(description="curves and landmarks only one of the two files has (left out)")


class MapResponse(BaseModel):
    revision: int
    k: int = Field(
        description="size of the maps handed out (solve.size): the session's k, or the combined energy's landmark "
        "prior's min(50, k) below 20 curves (their higher frequencies are not yet determined); solve says why"
    )
    solve: SolveStatement = Field(description="the energy, weights and map size the maps were solved with, and why")
    C_source_to_target: list[list[float]] = Field(description="C_MN: coefficients on M -> coefficients on N")
    C_target_to_source: list[list[float]] = Field(description="C_NM")


class PointsRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    vertices: list[VertexId] = Field(
        min_length=1, description="file ids of the vertices asked for", examples=[EXAMPLE_PATHS["source"]]
    )


class SessionChange(BaseModel):
    """What to change: the name, the sharing, or both (neither: nothing changes)."""

    model_config = ConfigDict(extra="forbid")
    name: str | None = Field(
        None,
        max_length=NAME_LENGTH,
        pattern=r"\S",
        description="a new name (not blank): the owner, an admin or, for a session shared editable, every user",
    )
    sharing: Sharing | None = Field(None, description=SHARING_DESCRIPTION)


class CollectionChange(BaseModel):
    model_config = ConfigDict(extra="forbid")
    sharing: Sharing = Field(description=SHARING_DESCRIPTION)


Role = Literal["owner", "manager", "annotator", "reviewer", "viewer"]


class RoleRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    role: Role = Field(
        description="viewer reads; reviewer reads and reviews; annotator reads and answers template curves on "
        "members; manager also adds and removes members, runs, shares and grants roles; owner everything"
    )


class RoleGrant(BaseModel):
    user: str = Field(description="the user's name")
    user_id: int = Field(description="the user's stable id")
    role: Role
    granted_by: str | None = Field(description="who granted it (None: the collection's creator, by making it)")
    granted_at: float = Field(description="when, UNIX seconds")


class AssigneeRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    user: str | None = Field(description="the annotator's name (null: assigned to no one)")


class SpreadRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    annotators: list[str] = Field(min_length=1, description="the users to spread the members over")
    members: list[str] | None = Field(None, description="the members to assign (default: those assigned to no one)")


REVIEW_HELP = (
    "open (never submitted), submitted (waiting for a reviewer; its curves are locked), changes_requested (sent "
    "back with a comment), accepted (its curves are locked)"
)


class MemberProgress(BaseModel):
    member: str
    shape_name: str
    session: str
    assignee: str | None = Field(description="the annotator it is assigned to (null: no one)")
    curves_done: int = Field(description="template curves answered on the member")
    curves_total: int
    done: bool = Field(description="every template curve answered")
    review: ReviewState = Field("open", description=REVIEW_HELP)


class MemberReview(BaseModel):
    member: str
    state: ReviewState = Field(description=REVIEW_HELP)
    submitted_by: str | None = Field(None, description="who submitted it last (null: never, or a removed user)")
    submitted_at: float | None = Field(None, description="when, UNIX seconds")
    reviewed_by: str | None = Field(None, description="who accepted it or requested changes last")
    reviewed_at: float | None = Field(None, description="when, UNIX seconds")
    comment: str = Field("", description="the reviewer's comment with their last decision")


class ReviewRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    decision: Literal["accept", "request_changes"] = Field(
        description="accept a submitted member, or send a submitted or accepted member back to its annotator"
    )
    comment: str = Field("", max_length=2000, description="what to change (shown to the annotator)")


COMMENT_TEXT = Field(pattern=r"^[^\x00]*[^\x00\s][^\x00]*$", description="what the comment says (not blank)")


class NewThread(BaseModel):
    """A comment that starts a thread, pinned to a vertex of one shape of the member's session."""

    model_config = ConfigDict(extra="forbid")
    text: str = COMMENT_TEXT
    side: Literal["source", "target"] = Field(
        description="the shape it points at: source (the template) or target (the member's shape)"
    )
    vertex: int = Field(
        ge=0,
        le=2**31 - 1,
        description="the vertex (a file id, 0-based) of that shape it points at",
        examples=[EXAMPLE_PATHS["source"][0]],  # else Swagger UI's example requests carry the bound, on no mesh
    )


class CommentReply(BaseModel):
    """A comment that answers another: it joins that comment's thread, at its vertex."""

    model_config = ConfigDict(extra="forbid")
    text: str = COMMENT_TEXT
    reply_to: str = Field(max_length=64, description="a comment of the thread this one answers")


CommentCreate = NewThread | CommentReply


class CommentResolve(BaseModel):
    model_config = ConfigDict(extra="forbid")
    resolved: bool = Field(description="true: the thread is resolved; false: open it again")


class ReviewCommentView(BaseModel):
    id: str
    member: str
    side: Literal["source", "target"] = Field(description="source: the template; target: the member's shape")
    vertex: int = Field(description="the vertex it points at (a file id)")
    text: str
    author: str | None = Field(description="who wrote it (null: a removed user)")
    created_at: float = Field(description="when, UNIX seconds")
    reply_to: str | None = Field(None, description="the first comment of the thread it answers (null: it starts one)")
    resolved_by: str | None = Field(None, description="who resolved the thread (on its first comment; null: open)")
    resolved_at: float | None = None


class AnnotationRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    user: str = Field(description="the annotator who annotates the member once more, independently")


class ManyAnnotationsRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    user: str = Field(description="the annotator who annotates the members once more, independently")
    members: list[str] | None = Field(
        None, description="the members (at most the collection's member count; default: every member)"
    )


class AnnotationView(BaseModel):
    member: str
    annotator: str | None = Field(description="whose annotation (the member's own session: its assignee)")
    session: str = Field(description="the session the annotator answers the template curves in")
    further: bool = Field(description="a further annotation, not the member's own session")


class CurveEndsAgreement(BaseModel):
    template_curve: str
    start: float | None = Field(
        description="geodesic distance between the two answers' starts, by sqrt(area) (null: on different "
        "components of the member)"
    )
    end: float | None = Field(description="between their ends, by sqrt(area)")


class PairAgreementView(BaseModel):
    a: str | None = Field(description="the first annotator")
    b: str | None = Field(description="the second annotator")
    session_a: str
    session_b: str
    map_distance: float | None = Field(
        description="mean geodesic distance on the member between the two maps' images of the compared template "
        "vertices, by sqrt(area of the member), over those on one component (null: none)"
    )
    unreachable: int = Field(description="compared template vertices whose two images lie on different components")
    endpoint_distance: float | None = Field(description="mean of the curves' start and end distances")
    curves: list[CurveEndsAgreement] = Field(description="per template curve both answered")


class MemberAgreement(BaseModel):
    member: str
    pairs: list[PairAgreementView] = Field(description="every pair of the member's annotations with curves")
    map_distance: float | None = Field(description="the mean over its pairs (null: no distance to compare)")
    flagged: bool = Field(description="map_distance above the threshold: review it")


class AnnotatorAgreementView(BaseModel):
    annotator: str
    members: int = Field(description="members they share with another annotator")
    map_distance: float | None = Field(
        description="the mean map distance of their pairs with the other annotators over those members (null: none)"
    )
    endpoint_distance: float | None = Field(description="the mean endpoint distance of those pairs")


class AnnotationAccuracyView(BaseModel):
    annotator: str | None = Field(description="who annotated (null: the member's own session, assigned to no one)")
    session: str
    further: bool = Field(description="a further annotation, not the member's own session")
    error: float | None = Field(
        description="mean geodesic distance on the member between the annotator's images of the compared template "
        "vertices and their true partners, by sqrt(area of the member); never at a curve end the annotator gave "
        "(null: nothing to score)"
    )
    scored: int = Field(description="template vertices scored")
    unreachable: int = Field(description="scored template vertices whose image lies on another component")


class MemberAccuracy(BaseModel):
    member: str
    annotations: list[AnnotationAccuracyView] = Field(description="each annotation of the member with curves")


class AnnotatorAccuracyView(BaseModel):
    annotator: str
    members: int = Field(description="check members they annotated with curves")
    error: float | None = Field(description="the mean of their errors over those members (null: none scored)")


class CheckReport(BaseModel):
    members: list[MemberAccuracy] = Field(description="the check members (with a ground truth), in order")
    annotators: list[AnnotatorAccuracyView] = Field(description="per annotator, by name")
    error: float | None = Field(description="the mean over every scored annotation (null: none)")


class TruthView(BaseModel):
    member: str
    rows: int = Field(description="template vertices (one row each)")
    known: int = Field(description="rows with a known partner (not -1)")
    set_by: str | None = Field(description="who gave it (null: a removed user)")
    set_at: float
    truth: list[int] | None = Field(
        None, description="per template vertex (file ids), its member vertex (file id, -1: unknown); GET only"
    )


class AgreementReport(BaseModel):
    members: list[MemberAgreement] = Field(description="the members annotated twice or more, both with curves")
    annotators: list[AnnotatorAgreementView] = Field(
        description="per annotator, by name: how far their answers lie from the others' (who disagrees with everyone)"
    )
    map_distance: float | None = Field(description="the mean over those members (null: none)")
    endpoint_distance: float | None = Field(description="the mean endpoint distance over their pairs")
    threshold: float = Field(description="CURVEFM_AGREEMENT_THRESHOLD, units of sqrt(area)")
    points: int = Field(description="template vertices compared (CURVEFM_AGREEMENT_POINTS at most)")
    flagged: list[str] = Field(description="the members above the threshold")
    checks: CheckReport | None = Field(
        None,
        description="each annotator's accuracy on the check members (those with a ground truth): only for those "
        "who manage the collection, so that annotators cannot tell a check member (null otherwise, or none)",
    )


class AnnotatorProgress(BaseModel):
    user: str
    assigned: int
    done: int
    next: str | None = Field(description="their first member not done yet (null: all done)")


class Assignments(BaseModel):
    members: list[MemberProgress]
    annotators: list[AnnotatorProgress] = Field(description="per annotator with members assigned, by name")


class WorkItem(MemberProgress):
    collection: str
    collection_name: str
    further: bool = Field(
        False, description="a further annotation of the member asked of you (double annotation), in its session"
    )


class UserInfo(BaseModel):
    name: str
    admin: bool


class NewToken(BaseModel):
    name: str
    token: str = Field(description="send it as 'Authorization: Bearer TOKEN'; it is shown only this once")


class SingleSignOnInfo(BaseModel):
    label: str = Field(description="the provider's name for the login page ('Sign in with ...')")
    login_url: str = Field(description="open it in the browser to sign in at the provider")


class LoginMethods(BaseModel):
    single_sign_on: SingleSignOnInfo | None = Field(description="null: not configured (CURVEFM_OIDC_ISSUER)")


class RefineRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    converter: str = "nearest-neighbor"
    params: dict = Field(default_factory=dict)


class CollectionView(BaseModel):
    collection: CollectionRecord
    members: list[MemberStatus] = Field(description="per member: basis, curves answered, the newest run's job")
    may: list[str] = Field(
        [],
        description="what you may do in it (your role and its sharing together): read, review, answer (your "
        "assigned members once members are assigned), answer_any, edit (members, runs), manage (sharing, roles, "
        "assignment), own (delete, owners)",
    )
    assignees: dict[str, str] = Field({}, description="member id -> the name of the annotator it is assigned to")
    reviews: dict[str, MemberReview] = Field({}, description="member id -> where it stands in review")


class CollectionSummary(BaseModel):
    id: str
    name: str
    owner: str
    sharing: Sharing
    template: str
    k: int
    n_curves: int = Field(description="template curves")
    n_members: int
    revision: int
    updated_at: float


class MembersRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")
    shapes: list[str] = Field(min_length=1, description="shape ids of the new members")


class AnswerRequest(BaseModel):
    """A member's curve answering a template curve: its target side clicked on the member."""

    model_config = ConfigDict(extra="forbid")
    template_curve: str = Field(description="t1, t2, ...: the template curve answered (answering it again replaces)")
    target: list[VertexId] = Field(
        min_length=2,
        description="waypoints on the member (file ids), or a whole path",
        examples=[EXAMPLE_PATHS["target"]],
    )
    explicit: bool = Field(False, description="target is a whole edge-connected vertex path")
    tracer: str | None = Field(None, description="the collection's tracer when none is named")
    tracer_params: dict = Field(default_factory=dict)
    weight: CurveWeight = 1.0


class RunRequest(RefineRequest):
    members: list[str] | None = Field(
        None, min_length=1, description="members to run (default all); the others keep the previous run's jobs"
    )
    only_ready: bool = Field(
        False, description="run only those of the members that have curves (else 409 names the ones without)"
    )
    only_accepted: bool = Field(False, description="run only those of the members a reviewer accepted")


class MemberMapsResponse(BaseModel):
    member: str
    shape: str
    session: str
    job: str
    revision: int = Field(description="the session revision the maps were computed from")
    C_template_to_member: list[list[float]]
    C_member_to_template: list[list[float]]
    map_member_to_template: list[int] = Field(description="line i: template vertex of member vertex i (file ids)")
    map_template_to_member: list[int] = Field(description="line j: member vertex of template vertex j (file ids)")
    report: dict = Field(description="quality figures, and which maps a refining converter kept and why")


class ComposedMaps(BaseModel):
    a: str
    b: str
    run: str
    map_a_to_b: list[int] = Field(description="line i: b's vertex of a's vertex i, via the template (file ids)")
    C_a_to_b: list[list[float]] = Field(
        description="C_Tb C_aT: coefficients on a -> coefficients on b, k_b x k_a; maps handed out at different "
        "sizes compose over the template frequencies both hold (docs: decisions, composing maps of different sizes)"
    )


WebhookEventName = Literal[
    "run.ended", "member.added", "member.removed", "member.completed", "member.submitted", "member.accepted"
]
"""The values of :class:`curvefm.webhooks.WebhookEvent` (tests/service/test_webhooks.py checks they agree)."""


class WebhookCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")
    url: str = Field(
        min_length=1,
        max_length=2000,
        description="where to POST: http:// or https://; an internal address (loopback, private, link-local) only "
        "where the operator allows it (CURVEFM_WEBHOOK_ALLOW_PRIVATE)",
        examples=["https://lab.example/curvefm-hook"],
    )
    events: list[WebhookEventName] = Field(
        min_length=1,
        max_length=16,
        description="what to be told: run.ended (a batch run's jobs all ended), member.added, member.removed, "
        "member.completed (a member's template curves all answered), member.submitted and member.accepted (the "
        "review stage)",
    )


class WebhookDelivery(BaseModel):
    id: str = Field(description="the delivery's id, also in its body and X-Curvefm-Delivery (the same on retries)")
    event: WebhookEventName
    state: Literal["pending", "delivered", "failed"] = Field(
        description="pending: not posted yet, or to be tried again at next_attempt_at; failed: its last try failed"
    )
    attempts: int
    created_at: float = Field(description="UNIX seconds")
    next_attempt_at: float
    last_attempt_at: float | None
    last_status: int | None = Field(description="the HTTP status the receiver answered last (None: no answer)")
    last_error: str | None = Field(description="why the last attempt failed")


class WebhookView(BaseModel):
    id: str
    collection: str
    url: str
    events: list[WebhookEventName]
    created_by: str | None = Field(description="who registered it (None: a removed user)")
    created_at: float
    last_delivery: WebhookDelivery | None = Field(description="its newest delivery, with how its last attempt went")


class WebhookCreated(WebhookView):
    secret: str = Field(
        description="signs every delivery (X-Curvefm-Signature: t=<unix time>,v1=<hex HMAC-SHA256 of "
        "'<t>.<body>'>); shown this once: keep it"
    )
