"""``/collections/{id}/webhooks``: URLs that receive a signed JSON POST when something happens in a collection
(:mod:`curvefm.webhooks`). Registering, listing, deleting them and reading their deliveries is for the
collection's owners and managers (and admins): a webhook's URL and log say what the lab works on."""

from __future__ import annotations

from dataclasses import asdict
from typing import Annotated

from fastapi import APIRouter, Query, Response

from curvefm.records.common import MAX_PAGE
from curvefm.records.webhooks import WebhookRow
from curvefm.service.auth import AUTHENTICATED, CurrentUser
from curvefm.service.deps import ServicesDep
from curvefm.service.errors import error_responses
from curvefm.service.models import WebhookCreate, WebhookCreated, WebhookDelivery, WebhookView
from curvefm.service.openapi import SchemaRoute
from curvefm.service.owned import LIMIT_HELP, OFFSET_HELP, TOTAL_HEADER, TOTAL_SCHEMA, paged
from curvefm.service.permissions import check_collection
from curvefm.service.settings import env_name
from curvefm.webhooks import WebhookEvent, checked_url

router = APIRouter(
    tags=["webhooks"],
    route_class=SchemaRoute,
    dependencies=AUTHENTICATED,
    responses=error_responses(401, 403, 503, 507),
)
ERRORS = error_responses(404, 422)


@router.post(
    "/collections/{collection_id}/webhooks",
    status_code=201,
    response_model=WebhookCreated,
    responses=error_responses(
        400, 404, 413, 422, described={400: "a URL that is not http(s), or names an internal address"}
    ),
)
def create_webhook(collection_id: str, body: WebhookCreate, services: ServicesDep, user: CurrentUser) -> WebhookCreated:
    """Register a URL to be told of ``events`` in the collection: an owner, a manager or an admin. The answer
    holds the webhook's ``secret`` (the only time it is shown). Each delivery is a POST of JSON ``{id, event,
    collection, created_at, data}`` with headers ``X-Curvefm-Event``, ``X-Curvefm-Delivery`` and
    ``X-Curvefm-Signature: t=<unix time>,v1=<hex HMAC-SHA256 of "<t>.<body>" with the secret>``; it is tried again
    (``CURVEFM_WEBHOOK_RETRIES`` times, waits doubling) until the receiver answers 2xx within
    ``CURVEFM_WEBHOOK_TIMEOUT``. 413 past ``CURVEFM_MAX_WEBHOOKS``. Audited as ``collection.webhook``."""
    check_collection(services, user, collection_id, "manage")
    settings = services.settings
    url = checked_url(body.url, settings.webhook_allow_private, env_name("webhook_allow_private"))
    events = [WebhookEvent(name) for name in body.events]
    row, secret = services.webhooks.create(collection_id, url, events, user.id, settings.max_webhooks)
    services.audit.record(user.name, "collection.webhook", collection_id, {"webhook": row.id, "events": row.events})
    return WebhookCreated(**_view(row).model_dump(), secret=secret)


@router.get("/collections/{collection_id}/webhooks", response_model=list[WebhookView], responses=ERRORS)
def list_webhooks(collection_id: str, services: ServicesDep, user: CurrentUser) -> list[WebhookView]:
    """The collection's webhooks, oldest first, each with its newest delivery: an owner, a manager or an admin.
    Secrets are never shown again."""
    check_collection(services, user, collection_id, "manage")
    return [_view(row) for row in services.webhooks.of_collection(collection_id)]


@router.delete("/collections/{collection_id}/webhooks/{webhook_id}", status_code=204, responses=ERRORS)
def delete_webhook(collection_id: str, webhook_id: str, services: ServicesDep, user: CurrentUser) -> Response:
    """Delete a webhook and its delivery log (what is still pending is not posted): an owner, a manager or an
    admin. Audited as ``collection.webhook_delete``."""
    check_collection(services, user, collection_id, "manage")
    services.webhooks.delete(collection_id, webhook_id)
    services.audit.record(user.name, "collection.webhook_delete", collection_id, {"webhook": webhook_id})
    return Response(status_code=204)


@router.get(
    "/collections/{collection_id}/webhooks/{webhook_id}/deliveries",
    response_model=list[WebhookDelivery],
    responses={200: {"headers": {TOTAL_HEADER: TOTAL_SCHEMA}}, **ERRORS},
)
def list_deliveries(
    collection_id: str,
    webhook_id: str,
    response: Response,
    services: ServicesDep,
    user: CurrentUser,
    limit: Annotated[int | None, Query(ge=1, le=MAX_PAGE, description=LIMIT_HELP)] = None,
    offset: Annotated[int, Query(ge=0, description=OFFSET_HELP)] = 0,
) -> list[WebhookDelivery]:
    """The webhook's deliveries, the newest first (the newest ``CURVEFM_WEBHOOK_LOG_SIZE`` are kept), each with
    its state and how its last attempt went: an owner, a manager or an admin."""
    check_collection(services, user, collection_id, "manage")
    rows, total = paged(lambda n, at: services.webhooks.deliveries(collection_id, webhook_id, n, at), limit, offset)
    response.headers[TOTAL_HEADER] = str(total)
    return [WebhookDelivery(**_delivery_fields(row)) for row in rows]


def _view(row: WebhookRow) -> WebhookView:
    last = None if row.last_delivery is None else WebhookDelivery(**_delivery_fields(row.last_delivery))
    return WebhookView(
        id=row.id,
        collection=row.collection_id,
        url=row.url,
        events=row.events,  # type: ignore[arg-type]  # the records hold WebhookEvent values
        created_by=row.created_by,
        created_at=row.created_at,
        last_delivery=last,
    )


def _delivery_fields(row) -> dict:
    fields = asdict(row)
    fields.pop("webhook_id")
    return fields
