"""Collection records on disk: ``<data>/collections/<id>.json``, written atomically with a per-collection file
lock, exactly as sessions' (:class:`curvefm.session.RecordFiles`)."""

from __future__ import annotations

from curvefm.collection.record import CollectionRecord
from curvefm.errors import NotFound, Unavailable, shown
from curvefm.session import RecordFiles


class UnknownCollection(NotFound):
    def __init__(self, collection_id: str):
        super().__init__(f"no collection with id '{shown(collection_id)}'")


class CollectionStore(RecordFiles[CollectionRecord]):
    kind, folder_name, model = "collection", "collections", CollectionRecord

    def unknown(self, record_id: str) -> NotFound:
        return UnknownCollection(record_id)

    def busy(self, record_id: str) -> Unavailable:
        return Unavailable(
            f"collection {record_id} is busy: another request held it for more than {self.lock_timeout_s:g} s "
            "(CURVEFM_SESSION_LOCK_TIMEOUT); try again"
        )
