"""Review of a collection's members and agreement between annotators.

A member moves ``open -> submitted -> accepted | changes_requested``: an annotator submits a member they may answer
once every template curve is answered; a reviewer (or a manager, an owner, an admin) accepts it or requests
changes with a comment; a changes-requested member is submitted again, and requesting changes on an accepted one
reopens it. While submitted or accepted the member's curves are locked (:func:`refuse_locked`). Every transition is
audited. Double annotation: a manager asks another annotator for a further, independent annotation of a member (a
session of its own); ``/agreement`` compares every two annotations of a member (:mod:`curvefm.collection.agreement`).
"""

from __future__ import annotations

from fastapi import APIRouter
from sqlalchemy import Connection

from curvefm.access import User
from curvefm.errors import Conflict, InvalidInput
from curvefm.records.collections import Annotation, Review, ReviewState
from curvefm.service.agreement import agreement_report
from curvefm.service.auth import AUTHENTICATED, CurrentUser
from curvefm.service.deps import Services, ServicesDep
from curvefm.service.errors import error_responses
from curvefm.service.models import (
    AgreementReport,
    AnnotationRequest,
    AnnotationView,
    ManyAnnotationsRequest,
    MemberReview,
    ReviewRequest,
)
from curvefm.service.openapi import SchemaRoute
from curvefm.service.permissions import annotator_named, check_collection
from curvefm.webhooks import WebhookEvent

router = APIRouter(
    tags=["collections"],
    route_class=SchemaRoute,
    dependencies=AUTHENTICATED,
    responses=error_responses(401, 403, 503, 507),
)
ERRORS = error_responses(404, 409, 422)
DECISIONS: dict[str, tuple[ReviewState, tuple[ReviewState, ...]]] = {
    "accept": ("accepted", ("submitted",)),
    "request_changes": ("changes_requested", ("submitted", "accepted")),
}
"""A reviewer's decision -> (the state it moves to, the states it moves from)."""

ANNOUNCED: dict[ReviewState, WebhookEvent] = {
    "submitted": WebhookEvent.MEMBER_SUBMITTED,
    "accepted": WebhookEvent.MEMBER_ACCEPTED,
}
"""The review moves the collection's webhooks are told of, in the transaction of the move."""


@router.post("/collections/{collection_id}/members/{member_id}/submit", response_model=MemberReview, responses=ERRORS)
def submit_member(collection_id: str, member_id: str, services: ServicesDep, user: CurrentUser) -> MemberReview:
    """Submit a member for review, once every template curve is answered on it (409 otherwise): whoever may answer
    it (its annotator, a manager, an owner, an admin); from open or changes requested. Its curves are locked until
    a reviewer requests changes. Audited as ``collection.submit``."""
    check_collection(services, user, collection_id, "answer", member_id)
    record = services.collections.record(collection_id)
    session = services.sessions.record(record.member(member_id).session)
    templates = {c.id for c in record.curves}
    missing = sorted(templates - {c.spec.template_curve for c in session.curves})
    if missing:
        raise Conflict(f"member {member_id} has template curves {', '.join(missing)} unanswered; answer them first")
    return _moved(services, user, collection_id, member_id, "submitted", ("open", "changes_requested"))


@router.post("/collections/{collection_id}/members/{member_id}/review", response_model=MemberReview, responses=ERRORS)
def review_member(
    collection_id: str, member_id: str, body: ReviewRequest, services: ServicesDep, user: CurrentUser
) -> MemberReview:
    """Accept a submitted member, or request changes (with a ``comment`` for its annotator) to a submitted or an
    accepted one, which unlocks its curves: a reviewer, a manager, an owner or an admin. Audited as
    ``collection.review``."""
    check_collection(services, user, collection_id, "review")
    to, allowed_from = DECISIONS[body.decision]
    return _moved(services, user, collection_id, member_id, to, allowed_from, body.comment)


@router.get("/collections/{collection_id}/reviews", response_model=list[MemberReview], responses=ERRORS)
def list_reviews(collection_id: str, services: ServicesDep, user: CurrentUser) -> list[MemberReview]:
    """Every member's review state, with who submitted and reviewed it last, when, and the comment; members in
    order. Whoever may read the collection."""
    check_collection(services, user, collection_id, "read")
    record = services.collections.record(collection_id)
    reviews = services.collections.records.reviews(collection_id)
    return [review_view(reviews.get(m.id, Review(m.id))) for m in record.members]


def review_view(review: Review) -> MemberReview:
    fields = {k: v for k, v in vars(review).items() if k != "member_id"}
    return MemberReview(member=review.member_id, **fields)


def _moved(
    services: Services,
    user: User,
    collection_id: str,
    member_id: str,
    to: ReviewState,
    allowed_from: tuple[ReviewState, ...],
    comment: str = "",
) -> MemberReview:
    records = services.collections.records
    event = ANNOUNCED.get(to)
    data = {"member": member_id, "by": user.name, **({"comment": comment} if comment else {})}

    def announce(tx: Connection) -> object:
        return event and services.webhooks.notify(collection_id, event, data, conn=tx)

    left = records.move_review(collection_id, member_id, to, allowed_from, user.id, comment, then=announce)
    action = "collection.submit" if to == "submitted" else "collection.review"
    detail = {"member": member_id, "from": left, "to": to, **({"comment": comment} if comment else {})}
    services.audit.record(user.name, action, collection_id, detail)
    return review_view(records.reviews(collection_id)[member_id])


# -- double annotation and agreement ---------------------------------------------------------------------------
@router.post(
    "/collections/{collection_id}/members/{member_id}/annotations",
    status_code=201,
    response_model=AnnotationView,
    responses=ERRORS,
)
def add_annotation(
    collection_id: str, member_id: str, body: AnnotationRequest, services: ServicesDep, user: CurrentUser
) -> AnnotationView:
    """Ask an annotator for a further, independent annotation of a member (double annotation): a new session of the
    collection (template -> the member's shape) that they answer the template curves in (``POST
    .../members/{member}/curves?annotator=NAME``, or the session's own routes). An owner, a manager or an admin;
    409 for a user who may not answer in the collection, or who annotates the member already (its assignee does
    in its own session). Audited as ``collection.annotate``."""
    check_collection(services, user, collection_id, "manage")
    target = annotator_named(services, collection_id, body.user)
    services.collections.record(collection_id).member(member_id)
    if services.collections.records.assignees(collection_id).get(member_id, (None,))[0] == target.id:
        raise Conflict(f"that user is the assignee of member {member_id}; they annotate it in its own session")
    with services.quotas.admit(user, "sessions", count=1) as conn:  # a session of the collection's, as members are
        session_id = services.collections.add_annotation(collection_id, member_id, target.id, conn)
    detail = {"member": member_id, "user": target.name, "session": session_id}
    services.audit.record(user.name, "collection.annotate", collection_id, detail)
    return AnnotationView(member=member_id, annotator=target.name, session=session_id, further=True)


@router.post(
    "/collections/{collection_id}/annotations",
    status_code=201,
    response_model=list[AnnotationView],
    responses={**ERRORS, **error_responses(400)},
)
def add_annotations(
    collection_id: str, body: ManyAnnotationsRequest, services: ServicesDep, user: CurrentUser
) -> list[AnnotationView]:
    """Ask an annotator for a further annotation of many members at once (``members``, by default every member):
    the members they annotate already or are the assignee of are skipped; at most the collection's member count
    named (400 beyond, 404 for an unknown member). Returns the annotations made, members in order; as ``POST
    .../members/{member}/annotations`` otherwise (who may ask, the quota, the audit, one entry a member)."""
    check_collection(services, user, collection_id, "manage")
    target = annotator_named(services, collection_id, body.user)
    record, records = services.collections.record(collection_id), services.collections.records
    if body.members is not None and len(body.members) > len(record.members):
        raise InvalidInput(f"name at most {len(record.members)} members, the collection's member count")
    named = {record.member(member_id).id for member_id in body.members} if body.members is not None else None
    theirs = {a.member_id for a in records.annotations(collection_id) if a.user_id == target.id}
    todo = [m.id for m in record.members if (named is None or m.id in named) and m.id not in theirs]
    with services.quotas.admit(user, "sessions", count=len(todo)) as conn:
        made = [(m, services.collections.add_annotation(collection_id, m, target.id, conn)) for m in todo]
    for member_id, session_id in made:
        detail = {"member": member_id, "user": target.name, "session": session_id}
        services.audit.record(user.name, "collection.annotate", collection_id, detail)
    return [AnnotationView(member=m, annotator=target.name, session=s, further=True) for m, s in made]


@router.get("/collections/{collection_id}/annotations", response_model=list[AnnotationView], responses=ERRORS)
def list_annotations(collection_id: str, services: ServicesDep, user: CurrentUser) -> list[AnnotationView]:
    """Every member's annotations: its own session (its assignee's) first, then the further ones by annotator;
    members in order. Whoever may read the collection."""
    check_collection(services, user, collection_id, "read")
    return [_annotation_view(a) for a in services.collections.records.annotations(collection_id)]


def _annotation_view(a: Annotation) -> AnnotationView:
    return AnnotationView(member=a.member_id, annotator=a.user, session=a.session_id, further=a.further)


@router.get("/collections/{collection_id}/agreement", response_model=AgreementReport, responses=ERRORS)
def get_agreement(collection_id: str, services: ServicesDep, user: CurrentUser) -> AgreementReport:
    """Agreement between annotators, for every member annotated twice or more (both annotations with curves): per
    pair of annotations the mean geodesic distance on the member between their pointwise maps of the template
    (at ``CURVEFM_AGREEMENT_POINTS`` template vertices spread by farthest-point sampling), and per template curve
    both answered the distance between their starts and between their ends, all by sqrt(area of the member); per
    member the mean over its pairs, flagged above ``CURVEFM_AGREEMENT_THRESHOLD``; and the project's means. For
    those who manage the collection, ``checks``: every annotation of a check member (one with a ground truth, ``PUT
    .../members/{member}/truth``) scored against its truth at the same template vertices, and each annotator's mean
    error. 409 while a basis it needs is not ready. Whoever may read the collection."""
    held = check_collection(services, user, collection_id, "read")
    record, settings = services.collections.record(collection_id), services.settings
    manages = "manage" in held
    return agreement_report(
        services.collections, record, settings.agreement_points, settings.agreement_threshold, manages
    )
