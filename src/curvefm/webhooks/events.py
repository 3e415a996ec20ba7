"""What a webhook can be told: the event names, and the body every delivery posts."""

from __future__ import annotations

import json
from enum import StrEnum
from typing import Any


class WebhookEvent(StrEnum):
    """The events of a collection (a project) a webhook may subscribe to.

    * ``run.ended``: every member job of a batch run ended (finished, failed, canceled or lost); fired by the
      process that records the last job's end, once per end of the run;
    * ``member.added`` / ``member.removed``: a member joined or left the collection;
    * ``member.completed``: a member's template curves are all answered;
    * ``member.submitted`` / ``member.accepted``: a member was submitted for review / accepted by a reviewer,
      announced in the transaction of the move (``curvefm.service.routes_reviews``).
    """

    RUN_ENDED = "run.ended"
    MEMBER_ADDED = "member.added"
    MEMBER_REMOVED = "member.removed"
    MEMBER_COMPLETED = "member.completed"
    MEMBER_SUBMITTED = "member.submitted"
    MEMBER_ACCEPTED = "member.accepted"


def event_body(
    delivery_id: str, event: WebhookEvent, collection_id: str, created_at: float, data: dict[str, Any]
) -> str:
    """The JSON a delivery posts: ``id`` (the same on every attempt: a receiver drops repeats by it), ``event``,
    ``collection``, ``created_at`` (UNIX seconds) and ``data`` (what the event says)."""
    document = {"id": delivery_id, "event": str(event), "collection": collection_id, "created_at": created_at}
    return json.dumps({**document, "data": data}, separators=(",", ":"), sort_keys=True)
