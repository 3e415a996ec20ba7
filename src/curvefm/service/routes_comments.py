"""Review comments: a thread per collection member, each comment pinned to a vertex of either shape of the
member's session (``source``: the template, ``target``: the member's shape), so that its annotator sees where a
reviewer points. Whoever may read the collection reads them; reviewers (managers, owners, admins) start threads;
they and whoever may answer the member (its annotator, and the annotators of its further annotations) reply, and
resolve or reopen threads; a comment's author (or an admin) deletes it. Comments do not depend on the review state
(a locked member is discussed too). Every comment, resolution and deletion is audited, and announced to the pages
that show the member's sessions (a ``comments`` session event)."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Response

from curvefm.access import User
from curvefm.collection import CollectionRecord
from curvefm.errors import Forbidden
from curvefm.records.comments import Comment, NewComment
from curvefm.service.auth import AUTHENTICATED, CurrentUser
from curvefm.service.deps import Services, ServicesDep, viewer
from curvefm.service.errors import error_responses
from curvefm.service.models import CommentCreate, CommentReply, CommentResolve, ReviewCommentView
from curvefm.service.openapi import SchemaRoute
from curvefm.service.permissions import check_collection, may_answer

router = APIRouter(
    tags=["collections"],
    route_class=SchemaRoute,
    dependencies=AUTHENTICATED,
    responses=error_responses(401, 403, 503, 507),
)
ERRORS = error_responses(404, 422)
COMMENTS = "/collections/{collection_id}/members/{member_id}/comments"
Part = Literal["start", "reply"]
REFUSALS: dict[Part, str] = {
    "start": "starting a comment thread needs the reviewer, manager or owner role",
    "reply": "replying to comments and resolving them needs the reviewer, manager or owner role, or answering the "
    "member (its annotator, or an annotator of a further annotation of it)",
}


@router.get(COMMENTS, response_model=list[ReviewCommentView], responses=ERRORS)
def list_comments(
    collection_id: str, member_id: str, services: ServicesDep, user: CurrentUser
) -> list[ReviewCommentView]:
    """The member's review comments, oldest first (a reply names its thread's first comment in ``reply_to``; a
    thread is resolved on its first comment). Whoever may read the collection."""
    check_collection(services, user, collection_id, "read")
    services.collections.record(collection_id).member(member_id)
    return [_view(comment) for comment in services.comments.thread(collection_id, member_id)]


@router.post(
    COMMENTS, status_code=201, response_model=ReviewCommentView, responses={**ERRORS, **error_responses(409, 413)}
)
def add_comment(
    collection_id: str, member_id: str, body: CommentCreate, services: ServicesDep, user: CurrentUser
) -> ReviewCommentView:
    """Start a thread pinned to ``vertex`` (a file id) of the ``side`` shape (``source``: the template, ``target``:
    the member's shape; 409 for a vertex the shape does not have, naming its vertex count): a reviewer, a manager,
    an owner or an admin. A reply (``reply_to``) joins that comment's thread at its vertex: they and whoever may
    answer the member (its annotator, and the annotators of its further annotations). Text up to
    ``CURVEFM_MAX_COMMENT_CHARS`` (422 past it), at most ``CURVEFM_MAX_REVIEW_COMMENTS`` comments a member (413).
    Audited as ``collection.comment``; the pages that show the member's sessions hear a ``comments`` event."""
    new = _checked_comment(services, user, collection_id, member_id, body)
    comment = services.comments.add(collection_id, member_id, new, user.id, services.settings.max_review_comments)
    detail = {"member": member_id, "comment": comment.id, "side": comment.side, "vertex": comment.vertex}
    services.audit.record(user.name, "collection.comment", collection_id, {**detail, "reply_to": comment.reply_to})
    _announce(services, collection_id, member_id)
    return _view(comment)


@router.patch(f"{COMMENTS}/{{comment_id}}", response_model=ReviewCommentView, responses=ERRORS)
def resolve_comment(
    collection_id: str, member_id: str, comment_id: str, body: CommentResolve, services: ServicesDep, user: CurrentUser
) -> ReviewCommentView:
    """Resolve the comment's thread (``resolved``: true) or open it again (false); answers the thread's first
    comment. Whoever may reply. Audited as ``collection.comment_resolve``."""
    _discussion(services, user, collection_id, member_id, "reply")
    first = services.comments.resolve(collection_id, member_id, comment_id, user.id, body.resolved)
    detail = {"member": member_id, "comment": first.id, "resolved": body.resolved}
    services.audit.record(user.name, "collection.comment_resolve", collection_id, detail)
    _announce(services, collection_id, member_id)
    return _view(first)


@router.delete(f"{COMMENTS}/{{comment_id}}", status_code=204, responses=ERRORS)
def delete_comment(
    collection_id: str, member_id: str, comment_id: str, services: ServicesDep, user: CurrentUser
) -> Response:
    """Delete a comment (a thread's first comment: with its replies): its author or an admin. Audited as
    ``collection.comment_delete``."""
    check_collection(services, user, collection_id, "read")
    comment = services.comments.get(collection_id, member_id, comment_id)
    if not (user.admin or comment.author_id == user.id):
        raise Forbidden("only the author of a comment or an admin may delete it")
    services.comments.delete(collection_id, member_id, comment_id)
    services.audit.record(
        user.name, "collection.comment_delete", collection_id, {"member": member_id, "comment": comment_id}
    )
    _announce(services, collection_id, member_id)
    return Response(status_code=204)


def _checked_comment(
    services: Services, user: User, collection_id: str, member_id: str, body: CommentCreate
) -> NewComment:
    """The new comment, once ``user`` may add it and a new thread's vertex is on its shape."""
    if isinstance(body, CommentReply):
        _discussion(services, user, collection_id, member_id, "reply")
        return NewComment(body.text, reply_to=body.reply_to)
    record = _discussion(services, user, collection_id, member_id, "start")
    _check_vertex(services, record, member_id, body.side, body.vertex)
    return NewComment(body.text, body.side, body.vertex)


def _discussion(services: Services, user: User, collection_id: str, member_id: str, part: Part) -> CollectionRecord:
    """The collection, when ``user`` may take that ``part`` in the member's comments (404: they may not read it,
    or no such member; 403: they may read it only)."""
    held = check_collection(services, user, collection_id, "read")
    record = services.collections.record(collection_id)
    record.member(member_id)
    if "review" in held or (part == "reply" and _answers(services, user, collection_id, member_id, held)):
        return record
    raise Forbidden(f"collection {collection_id}: {REFUSALS[part]}; ask its owner or a manager")


def _answers(services: Services, user: User, collection_id: str, member_id: str, held: frozenset) -> bool:
    """Whether ``user`` may answer the member, or makes a further annotation of it (while they may answer)."""
    standing = services.collections.records.standing(collection_id, viewer(user), member_id)
    if standing is not None and may_answer(user, standing, held):
        return True
    return "answer" in held and services.comments.annotates(collection_id, member_id, user.id)


def _announce(services: Services, collection_id: str, member_id: str) -> None:
    """Tell the pages that show the member's sessions (its own, its further annotations') that its comments
    changed, in every API process (as the sessions' own changes are)."""
    for session_id, revision in services.comments.sessions(collection_id, member_id).items():
        services.live.notify(session_id, {"kind": "comments", "revision": revision})


def _check_vertex(services: Services, record: CollectionRecord, member_id: str, side: str, vertex: int) -> None:
    """409 unless ``vertex`` (a file id) is a vertex on the surface of the ``side`` shape."""
    shape = record.template if side == "source" else record.member(member_id).shape
    services.live.mesh(shape, side).internal_ids([vertex], f"{side} vertex")


def _view(comment: Comment) -> ReviewCommentView:
    fields = {k: v for k, v in vars(comment).items() if k not in ("member_id", "author_id")}
    return ReviewCommentView(member=comment.member_id, **fields)
