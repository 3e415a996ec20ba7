"""``/audit``: the audit log (who created, changed, shared or deleted what), for admins."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated

from fastapi import APIRouter, Query, Response
from pydantic import BeforeValidator

from curvefm.errors import Forbidden
from curvefm.records.common import MAX_OFFSET, MAX_PAGE
from curvefm.service.auth import CurrentUser
from curvefm.service.deps import ServicesDep
from curvefm.service.errors import error_responses
from curvefm.service.models import AuditEvent

router = APIRouter(tags=["audit"])
IsoTime = Annotated[datetime, BeforeValidator(datetime.fromisoformat)]
"""An ISO 8601 time, as the schema's date-time says (pydantic alone would read "0.5" as a Unix time)."""


@router.get(
    "/audit",
    response_model=list[AuditEvent],
    responses={
        200: {"headers": {"X-Total-Count": {"description": "how many events match", "schema": {"type": "integer"}}}},
        **error_responses(401, 403, 422),
    },
)
def read_audit(
    response: Response,
    caller: CurrentUser,
    services: ServicesDep,
    limit: Annotated[int, Query(ge=1, le=MAX_PAGE, description="the last this many events")] = 100,
    offset: Annotated[
        int, Query(ge=0, le=MAX_OFFSET, description="skip this many of the newest (the page before)")
    ] = 0,
    since: Annotated[IsoTime | None, Query(description="only events at or after this ISO 8601 time")] = None,
    user: Annotated[str | None, Query(max_length=64, description="only events of this user")] = None,
) -> list[dict]:
    """Events oldest first: the last ``limit`` after skipping the ``offset`` newest (``X-Total-Count``: how many
    match); admins only (403 for other users)."""
    if not caller.admin:
        raise Forbidden(f"the audit log is for admins; {caller.name} is not one")
    page = services.audit.page(limit=limit, offset=offset, since=since, user=user)
    response.headers["X-Total-Count"] = str(page.total)
    return page.items[::-1]
