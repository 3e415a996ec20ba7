"""Webhooks: a collection (a project) registers URLs that receive a signed JSON POST when something happens in
it (:class:`WebhookEvent`).

* ``events``: the event names and the body a delivery posts;
* ``signing``: the ``X-Curvefm-Signature`` header (HMAC-SHA256 over the timestamp and the body) and its check;
* ``addresses``: which URLs a webhook may post to (no internal addresses unless the operator allows them);
* ``delivery``: the loop that posts the outbox's deliveries (:mod:`curvefm.records.webhooks`), with bounded
  retries and timeouts.

To announce an event, call :meth:`curvefm.records.webhooks.Webhooks.notify` (the service has one as
``services.webhooks``): ``notify(collection_id, WebhookEvent.MEMBER_ACCEPTED, {"member": "m3", ...})``.
"""

from curvefm.webhooks.addresses import check_resolved, checked_url
from curvefm.webhooks.events import WebhookEvent, event_body
from curvefm.webhooks.signing import SIGNATURE_HEADER, new_secret, signature, verify

__all__ = [
    "SIGNATURE_HEADER",
    "WebhookEvent",
    "check_resolved",
    "checked_url",
    "event_body",
    "new_secret",
    "signature",
    "verify",
]
