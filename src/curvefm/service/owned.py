"""Owned, shared records (sessions and collections) as their routes list, share and delete them, written once for
both kinds.

Who may do what is :mod:`curvefm.service.permissions`; each kind's editor (the domain) makes the change; an
:class:`Owned` kind checks the permission before and writes the audit entry (``<kind>.share``,
``<kind>.delete``) after, so the routes stay one call each.
"""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, Protocol, TypeVar

from pydantic import BaseModel

from curvefm.access import User
from curvefm.collection import CollectionRecord
from curvefm.errors import CurvefmError
from curvefm.records.common import MAX_PAGE, Page
from curvefm.service.deps import Services, results_dir
from curvefm.service.permissions import Need, collection_for, session_for
from curvefm.session import SessionRecord, Sharing

R = TypeVar("R", SessionRecord, CollectionRecord)
R_co = TypeVar("R_co", bound=SessionRecord | CollectionRecord, covariant=True)
Summary = TypeVar("Summary", bound=BaseModel)


class OwnedEditor(Protocol[R_co]):
    """What :class:`curvefm.session.SessionEditor` and :class:`curvefm.collection.CollectionEditor` share."""

    def share(self, record_id: str, sharing: Sharing, /) -> R_co: ...

    def delete(self, record_id: str, /) -> list[str]:
        """Delete the record (and what it holds); returns the ids of the refinement jobs run from it."""
        ...


@dataclass(frozen=True)
class Owned(Generic[R]):
    kind: str
    """``session`` or ``collection``, as the audit actions name it."""
    find: Callable[[Services, User, str, Need], R]
    """The record when the user may ``need`` it: 404 for one they may not see, 403 for one they may not change so."""
    editor: Callable[[Services], OwnedEditor[R]]

    def share(self, services: Services, user: User, record_id: str, sharing: Sharing) -> R:
        """Change who may use the record: its owner or an admin (and a collection's managers)."""
        self.find(services, user, record_id, "manage")
        record = self.editor(services).share(record_id, sharing)
        services.audit.record(user.name, f"{self.kind}.share", record_id, {"sharing": sharing})
        return record

    def delete(self, services: Services, user: User, record_id: str) -> None:
        """Delete the record and the result files of the refinement jobs run from it (running ones are canceled
        first): its owner(s) or an admin."""
        self.find(services, user, record_id, "own")
        for job_id in self.editor(services).delete(record_id):
            discard_job(services, job_id)
        services.audit.record(user.name, f"{self.kind}.delete", record_id)


SESSIONS = Owned("session", session_for, lambda services: services.sessions)
COLLECTIONS = Owned("collection", collection_for, lambda services: services.collections)


T = TypeVar("T")
TOTAL_HEADER = "X-Total-Count"
TOTAL_SCHEMA = {"description": "how many records the list has in all", "schema": {"type": "integer"}}
LIMIT_HELP = f"at most this many (1 to {MAX_PAGE}; none: all)"
OFFSET_HELP = "skip this many first"


def paged(fetch: Callable[[int, int], Page[T]], limit: int | None, offset: int) -> tuple[list[T], int]:
    """The items of a list from ``offset``: ``limit`` of them (one page, sliced by the database), or all when
    ``limit`` is None (page after page of :data:`MAX_PAGE`); and how many the list has in all. ``fetch(limit,
    offset)`` is the records module's page."""
    items: list[T] = []
    while True:
        want = MAX_PAGE if limit is None else limit - len(items)
        page = fetch(want, offset + len(items))
        items += page.items
        if limit is not None or len(page.items) < want or offset + len(items) >= page.total:
            return items, page.total


def summary(model: type[Summary], record: BaseModel, **counts: int) -> Summary:
    """The list entry ``model`` of ``record``: the fields they share, and ``counts`` (``n_curves=...``)."""
    return model(**counts, **record.model_dump(include=set(model.model_fields) - set(counts)))


def discard_job(services: Services, job_id: str) -> None:
    """Cancel the job if it still runs and delete its result files."""
    with contextlib.suppress(CurvefmError):  # it ended already, or the queue forgot it
        services.queue.cancel(job_id)
    shutil.rmtree(results_dir(services, job_id), ignore_errors=True)
