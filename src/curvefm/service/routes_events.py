"""``GET /sessions/{id}/events``: a session's changes as they happen, for the pages that show it
(:mod:`curvefm.service.session_events`)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import StreamingResponse
from starlette.concurrency import run_in_threadpool

from curvefm.service.auth import AUTHENTICATED, CurrentUser, identify
from curvefm.service.deps import ServicesDep
from curvefm.service.errors import error_responses
from curvefm.service.permissions import session_for
from curvefm.service.session_events import SessionEvents

router = APIRouter(tags=["sessions"], dependencies=AUTHENTICATED, responses=error_responses(401, 403, 503))

DESCRIPTION = """The session's changes as they happen, as Server-Sent Events (`text/event-stream`; a browser's
`EventSource` sends the login cookie), whichever API process made them; reading the session is enough. A comment
line every `CURVEFM_EVENTS_KEEPALIVE` seconds keeps proxies from closing an idle stream. 429 when you have
`CURVEFM_MAX_EVENT_STREAMS` streams open already (across the API processes).

Each event is one `data:` line of JSON with its `kind` and the session's `revision` then:

* `hello`: first, with `viewers` (the names of the users who have the session open, you included); compare its
  `revision` with yours (a reconnect after missed events).
* `curve-added`, `curve-removed`, `curve-replaced` (with `curve`, its id), `renamed`, `sharing` (with `sharing`),
  `changed` (another API process's change, seen by its poller without Redis): reload what you show when `revision`
  is past yours (`GET /sessions/{id}`, its transfer, its quality).
* `prior`: the map of this revision improved (its landmark prior landed): read the transfer again.
* `refined`: a refinement job of the session ended (`job` and `state` with Redis): list the refinements again.
* `comments`: the review comments of the session's collection member changed (added, replied to, resolved,
  reopened, deleted; heard by the member's own session and its further annotations'): list them again.
* `viewers`: who has the session open changed (`viewers`).
* `reconnected`: the server lost events for a while (Redis restarted): compare revisions.
* `deleted`, `forbidden` (its sharing or your role no longer lets you read it), `logged-out` (the credential the
  stream was opened with ended: a logout, a rotated token), `closing` (the server shuts down): the stream ends (an
  idle stream checks its credential and access at each keep-alive); a browser's EventSource reconnects after
  `retry` ms on its own (a deleted session answers 404 then)."""


@router.get(
    "/sessions/{session_id}/events",
    description=DESCRIPTION,
    response_class=StreamingResponse,
    responses={
        200: {
            "content": {"text/event-stream": {"schema": {"type": "string"}}},
            "description": "Server-Sent Events (see the route's description)",
        },
        **error_responses(404, 422, 429),
    },
)
async def session_events(session_id: str, request: Request, services: ServicesDep, user: CurrentUser):
    record = await run_in_threadpool(session_for, services, user, session_id, "read")
    events: SessionEvents = request.app.state.events
    stream = await events.open(user, record, credential=lambda: identify(request))
    headers = {"Cache-Control": "no-cache", "X-Accel-Buffering": "no"}  # no proxy may hold the events back
    return StreamingResponse(events.feed(stream), media_type="text/event-stream", headers=headers)
