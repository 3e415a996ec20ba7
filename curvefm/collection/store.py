"""Collection records on disk: ``<data>/collections/<id>.json``, written atomically with a per-collection file
lock, exactly as sessions' (:class:`curvefm.session.RecordFiles`)."""

from __future__ import annotations

from curvefm.collection.record import CollectionRecord
from curvefm.errors import NotFound, shown
from curvefm.session import RecordBusy, RecordFiles


class UnknownCollection(NotFound):
    def __init__(self, collection_id: str):
        super().__init__(f"no collection with id '{shown(collection_id)}'")


class CollectionBusy(RecordBusy):
    kind = "collection"


class CollectionStore(RecordFiles[CollectionRecord]):
    kind, folder_name, model = "collection", "collections", CollectionRecord
    unknown, busy = UnknownCollection, CollectionBusy
