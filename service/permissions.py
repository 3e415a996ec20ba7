"""Who may do what, in one place. Admins may do everything.

* Sessions: the owner may do everything; others as its ``sharing`` says: ``private`` (nothing: the session
  answers 404, as if it did not exist), ``read`` (read it, its maps and transfers, and refine from it), ``edit``
  (also change its curves). Sharing and deleting are the owner's (403 for others who can see it).
* Collections: as sessions; their member sessions are shared as the collection is.
* Shapes and their bases are a shared library: every user sees and uses them; only an uploader deletes them.
* Jobs: a basis job is visible to every user (its shape is, and a second request for the same basis joins
  it); a refinement job to its owner and, once finished, to whoever may read its session. Only the owner
  cancels or retries a job. A job's result files follow the job.
"""

from __future__ import annotations

from typing import Literal

from curvefm.access import User
from curvefm.collection import CollectionRecord, UnknownCollection
from curvefm.errors import Conflict, CurvefmError, Forbidden, NotFound
from curvefm.service.deps import Services
from curvefm.session import SessionRecord, UnknownSession
from curvefm.workers.interface import JobInfo, unknown_job

Need = Literal["read", "edit", "manage"]


Shared = SessionRecord | CollectionRecord
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
    return _checked(services.sessions.record(session_id), user, need, "session", UnknownSession)


def collection_for(services: Services, user: User, collection_id: str, need: Need) -> CollectionRecord:
    """As :func:`session_for`, for a collection (its member sessions are shared alike)."""
    return _checked(services.collections.record(collection_id), user, need, "collection", UnknownCollection)


def _checked(record: Shared, user: User, need: Need, kind: str, unknown: type[CurvefmError]) -> Shared:
    if not may_read(user, record):
        raise unknown(record.id)
    if need == "edit" and not may_edit(user, record):
        raise Forbidden(f"{kind} {record.id} is shared read-only by its owner {record.owner}; ask them to share "
                        f"it editable, or make your own {kind} on the same shapes")
    if need == "manage" and not may_manage(user, record):
        raise Forbidden(f"only the owner of {kind} {record.id} ({record.owner}) or an admin may share or delete it")
    return record


def check_shape_manager(services: Services, user: User, shape_id: str, action: str) -> None:
    if not services.store.has_mesh(shape_id):
        raise NotFound(f"no shape with id '{shape_id}'")
    uploaders = services.store.uploaders(shape_id)
    if not (user.admin or user.name in uploaders):
        raise Forbidden(f"only an uploader of shape {shape_id} ({', '.join(uploaders) or 'unknown'}) or an admin "
                        f"may {action}")


def check_unused(services: Services, user: User, shape_id: str, action: str) -> None:
    """409 while a session uses the shape, naming the sessions ``user`` may see and counting the others."""
    using = [r for r in services.records.list() if shape_id in (r.source, r.target)]
    if not using:
        return
    named = [f"session {r.id}" for r in using if may_read(user, r)]
    hidden = len(using) - len(named)
    listed = ", ".join(named + ([f"{hidden} private session(s) of other users"] if hidden else []))
    raise Conflict(f"cannot {action}: shape {shape_id} is used by {listed}; delete those sessions first (their "
                   "owners or an admin can)")


def job_for(services: Services, user: User, job_id: str, act: bool = False) -> JobInfo:
    """The job, when ``user`` may see it (404 otherwise) and, to ``act`` on it (cancel, retry), owns it (403
    otherwise)."""
    info = services.queue.get(job_id)
    if not _may_see(services, user, info):
        raise unknown_job(job_id)
    if act and not (user.admin or info.owner == user.name):
        raise Forbidden(
            f"only the user who started job {job_id} ({info.owner or 'unknown'}) or an admin may cancel or retry it"
        )
    return info


def _may_see(services: Services, user: User, info: JobInfo) -> bool:
    if user.admin or info.owner == user.name or info.kind == "basis":
        return True
    session_id = (info.result or {}).get("session")
    if session_id is None:
        return False
    try:
        return may_read(user, services.sessions.record(session_id))
    except CurvefmError:  # the session was deleted since
        return False
