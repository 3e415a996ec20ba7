"""Who may do what, in one place. Admins may do everything.

* Sessions: the owner may do everything; others as its ``sharing`` says: ``private`` (nothing: the session
  answers 404, as if it did not exist), ``read`` (read it, its maps and transfers, and refine from it), ``edit``
  (also change its curves and its name: a name is the session's content, as its curves are). Sharing and
  deleting are the owner's (403 for others who can see it).
* Collections are projects: their creator owns them, and their owners and managers grant roles in them to named
  users (:data:`ROLE_CAPABILITIES`): ``viewer`` reads; ``reviewer`` reads (and reviews); ``annotator`` reads and
  answers template curves on members (edits the member sessions' curves; once any member is assigned, only the
  members assigned to them); ``manager`` also answers every member, assigns members, adds and removes
  members, starts runs, shares and grants roles (but not ``owner``); ``owner`` also deletes the collection and
  grants or takes away ``owner``. The collection's ``sharing`` is a lab-wide default granting every user the
  capabilities of :data:`SHARING_CAPABILITIES` (``read`` as a viewer; ``edit`` also answers, adds and removes
  members and starts runs); a user holds the union of their role's and the sharing's, so the higher of the two.
  A collection they hold neither for answers 404. Member sessions are shared as their collection is, and a role
  in the collection reaches its member sessions (read; edit for those who may answer; share and delete for its
  owners), and a further annotation's session (double annotation) as if its member were assigned to its
  annotator. ``review`` accepts submitted members or sends them back; a member submitted or accepted is locked:
  edits of its session (curves, name) answer 409 for everyone, admins too, until a reviewer requests changes.
* Shapes and their bases are a shared library: every user sees and uses them; only an uploader deletes them.
* Jobs: a basis job is visible to every user (its shape is, and a second request for the same basis joins
  it); a refinement job to its owner and, once finished, to whoever may read its session. Only the owner
  cancels or retries a job. A job's result files follow the job.
"""

from __future__ import annotations

from typing import Literal, TypeVar

from curvefm.access import User
from curvefm.collection import CollectionRecord, UnknownCollection
from curvefm.errors import Conflict, CurvefmError, Forbidden, NotFound, shown
from curvefm.records.collections import Standing
from curvefm.service.deps import Services, viewer
from curvefm.session import SessionRecord, UnknownSession
from curvefm.workers.interface import JobInfo, unknown_job

Need = Literal["read", "review", "answer", "answer_any", "edit", "manage", "own"]
"""What a request needs. Sessions know ``read``, ``edit`` (``answer`` alike) and ``manage`` (``own`` alike);
collections all. ``answer`` is the annotators' (once members are assigned, only their own members);
``answer_any`` answers every member whoever it is assigned to."""
EVERYTHING: frozenset[Need] = frozenset(("read", "review", "answer", "answer_any", "edit", "manage", "own"))
ROLE_CAPABILITIES: dict[str, frozenset[Need]] = {
    "owner": EVERYTHING,
    "manager": EVERYTHING - {"own"},
    "annotator": frozenset(("read", "answer")),
    "reviewer": frozenset(("read", "review")),
    "viewer": frozenset(("read",)),
}
SHARING_CAPABILITIES: dict[str, frozenset[Need]] = {
    "private": frozenset(),
    "read": frozenset(("read",)),
    "edit": frozenset(("read", "answer", "answer_any", "edit")),
}
REFUSALS: dict[Need, str] = {
    "review": "reviewing its members needs the reviewer, manager or owner role",
    "answer": "answering its template curves needs the annotator, manager or owner role (or the collection "
    "shared editable)",
    "answer_any": "this member is not assigned to you, and annotators answer the members assigned to them "
    "(GET /me/work lists yours)",
    "edit": "adding or removing members and starting runs need the manager or owner role (or the collection "
    "shared editable)",
    "manage": "sharing it and granting roles need the manager or owner role",
    "own": "deleting it and granting or taking away the owner role need the owner role",
}


Shared = SessionRecord | CollectionRecord
S = TypeVar("S", SessionRecord, CollectionRecord)
"""What has an owner and a sharing: sessions and collections (a collection's member sessions share alike)."""


def may_read(user: User, record: Shared) -> bool:
    return user.admin or record.owner == user.name or record.sharing != "private"


def may_edit(user: User, record: Shared) -> bool:
    return user.admin or record.owner == user.name or record.sharing == "edit"


def may_manage(user: User, record: Shared) -> bool:
    return user.admin or record.owner == user.name


def session_for(services: Services, user: User, session_id: str, need: Need) -> SessionRecord:
    """The record, when ``user`` may ``need`` it: 404 for a session they may not see, 403 for one they see
    but may not change so."""
    record = services.sessions.record(session_id)
    if not (user.admin or record.owner == user.name):
        _checked(record, user, need, "session", UnknownSession, _member_session_needs(services, user, session_id))
    if need in ("edit", "answer"):
        refuse_locked(services, session_id)
    return record


def refuse_locked(services: Services, session_id: str) -> None:
    """409 when the session is a member's that is submitted or accepted: its curves and name wait for a reviewer
    (who sends it back with changes requested to reopen it)."""
    locked = services.collections.records.locked_member(session_id)
    if locked is not None:
        collection_id, member_id, state = locked
        raise Conflict(
            f"member {member_id} of collection {collection_id} is {state}: its curves may not change until a "
            "reviewer requests changes (POST .../review)"
        )


def collection_for(services: Services, user: User, collection_id: str, need: Need) -> CollectionRecord:
    """The record, when ``user`` may ``need`` it (their role or the lab-wide sharing, checked in one query): 404
    for a collection they may not see, 403 for one they see but may not use so (naming no one)."""
    check_collection(services, user, collection_id, need)
    return services.collections.record(collection_id)


def check_collection(
    services: Services, user: User, collection_id: str, need: Need, member: str | None = None
) -> frozenset[Need]:
    """As :func:`collection_for` without reading the record; returns what ``user`` may do in the collection.
    ``member``: the member an ``answer`` is for (an annotator's must be assigned to them once members are)."""
    standing = services.collections.records.standing(collection_id, viewer(user), member)
    held = capabilities(user, standing)
    if standing is None or "read" not in held:
        raise UnknownCollection(collection_id)
    if need == "answer" and member is not None and not may_answer(user, standing, held):
        need = "answer_any"
    if need not in held:
        raise Forbidden(f"collection {collection_id}: {REFUSALS[need]}; ask its owner or a manager")
    return held


def capabilities(user: User, standing: Standing | None) -> frozenset[Need]:
    """What ``user`` may do in a collection: an admin or its creator everything, others the union of their
    role's capabilities and the sharing's."""
    if standing is None:
        return frozenset()
    if user.admin or standing.creator:
        return EVERYTHING
    return ROLE_CAPABILITIES.get(standing.role or "", frozenset()) | SHARING_CAPABILITIES[standing.sharing]


def check_annotator(services: Services, collection_id: str, target: User) -> None:
    """409 unless ``target`` may answer in the collection (an annotator, a manager, an owner)."""
    standing = services.collections.records.standing(collection_id, viewer(target))
    if "answer" not in capabilities(target, standing):
        raise Conflict(
            f"user '{target.name}' may not answer in collection {collection_id}; grant them the annotator role "
            "first (PUT .../roles/{user})"
        )


def annotator_named(services: Services, collection_id: str, name: str) -> User:
    """The user of that name, when they may answer in the collection (404: no such user; 409: they may not)."""
    target = services.users.get(name)
    if target is None:
        raise NotFound(f"no user named '{shown(name)}'")
    check_annotator(services, collection_id, target)
    return target


def may_answer(user: User, standing: Standing, held: frozenset[Need]) -> bool:
    """Whether ``user`` may answer the member ``standing`` was read for: anyone holding ``answer_any``, an
    annotator while no member is assigned or when it is assigned to them."""
    if "answer_any" in held:
        return True
    return "answer" in held and (not standing.assigning or standing.assignee == user.id)


def _member_session_needs(services: Services, user: User, session_id: str) -> frozenset[Need]:
    """What a role in the collection of a member session lets ``user`` do to the session."""
    records, asking = services.collections.records, viewer(user)
    standing = records.member_standing(session_id, asking) or records.annotation_standing(session_id, asking)
    if standing is None:
        return frozenset()
    held = capabilities(user, standing)
    needs: set[Need] = {"read"} if "read" in held else set()
    needs |= {"edit"} if may_answer(user, standing, held) else set()
    return frozenset(needs | ({"manage"} if "own" in held else set()))


def _checked(
    record: S, user: User, need: Need, kind: str, unknown: type[CurvefmError], more: frozenset[Need] = frozenset()
) -> S:
    """``more``: what the user may do beyond the record's own owner and sharing (a role in its collection)."""
    need = {"answer": "edit", "own": "manage"}.get(need, need)  # type: ignore[assignment]
    if not (may_read(user, record) or "read" in more):
        raise unknown(record.id)
    if need == "edit" and not (may_edit(user, record) or "edit" in more):
        raise Forbidden(
            f"{kind} {record.id} is shared read-only by its owner; ask them to share "
            f"it editable, or make your own {kind} on the same shapes"
        )
    if need == "manage" and not (may_manage(user, record) or "manage" in more):
        raise Forbidden(f"only the owner of {kind} {record.id} or an admin may share or delete it")
    return record


def check_shape_manager(services: Services, user: User, shape_id: str, action: str) -> None:
    if not services.store.has_mesh(shape_id):
        raise NotFound(f"no shape with id '{shape_id}'")
    if not (user.admin or user.id in services.shapes.uploader_ids(shape_id)):
        raise Forbidden(f"only an uploader of shape {shape_id} or an admin may {action}")


def check_unused(services: Services, user: User, shape_id: str, action: str) -> None:
    """409 while a session uses the shape, naming the sessions ``user`` may see and counting the others (one
    query, whatever the number of sessions)."""
    use = services.shapes.using(shape_id, viewer(user))
    if not use:
        return
    named = [f"session {s}" for s in use.sessions] + [f"collection {c}" for c in use.collections]
    hidden = [f"{use.hidden} private record(s) of other users"] if use.hidden else []
    raise Conflict(
        f"cannot {action}: shape {shape_id} is used by {', '.join(named + hidden)}; delete those first (their "
        "owners or an admin can)"
    )


def job_for(services: Services, user: User, job_id: str, act: bool = False) -> JobInfo:
    """The job, when ``user`` may see it (404 otherwise) and, to ``act`` on it (cancel, retry), owns it (403
    otherwise)."""
    info = services.queue.get(job_id)
    if not _may_see(services, user, info):
        raise unknown_job(job_id)
    if act and not (user.admin or info.owner == user.name):
        raise Forbidden(f"only the user who started job {job_id} or an admin may cancel or retry it")
    return info


def _may_see(services: Services, user: User, info: JobInfo) -> bool:
    if user.admin or info.owner == user.name or info.kind == "basis":
        return True
    session_id = (info.result or {}).get("session")
    if session_id is None:
        return False
    try:
        session_for(services, user, session_id, "read")  # (a role in the session's collection counts)
    except CurvefmError:  # not theirs to read, or deleted since
        return False
    return True
