"""Posting the outbox's deliveries: a loop in each API process claims the due ones, posts each with its
signature, and records how it went. A delivery that does not answer 2xx within the timeout is tried again after
``retry_delay_s``, doubling each time, until it has been tried ``1 + retries`` times. Redirects are not followed
(a redirect could lead where the address check refused to go)."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import httpx

from curvefm.errors import CurvefmError
from curvefm.records.webhooks import Due, Webhooks
from curvefm.webhooks.addresses import check_resolved
from curvefm.webhooks.signing import SIGNATURE_HEADER, signature

log = logging.getLogger("curvefm.webhooks")
BATCH = 20
MAX_ERROR_LENGTH = 300
USER_AGENT = "curvefm-webhooks/1"


@dataclass(frozen=True)
class DeliveryPolicy:
    timeout_s: float
    retries: int
    retry_delay_s: float
    allow_private: bool
    allow_private_setting: str = "CURVEFM_WEBHOOK_ALLOW_PRIVATE"

    def retry_at(self, attempts_before: int, now: float) -> float | None:
        """When to try again after a failed attempt (None: it was the last)."""
        if attempts_before >= self.retries:
            return None
        return now + self.retry_delay_s * 2**attempts_before


class Poster(Protocol):
    def post(self, url: str, *, content: bytes, headers: dict[str, str]) -> httpx.Response: ...


def deliver_due(outbox: Webhooks, policy: DeliveryPolicy, client: Poster, now: Callable[[], float] = time.time) -> int:
    """Claim the due deliveries and attempt each once; how many were attempted."""
    due = outbox.claim(now(), lease_s=policy.timeout_s * 2 + 5, limit=BATCH)
    for delivery in due:
        status, error = attempt(delivery, policy, client)
        at = now()
        retry_at = None if status is not None and 200 <= status < 300 else policy.retry_at(delivery.attempts, at)
        outbox.attempted(delivery.id, at, status, error, retry_at)
        if error or (status is not None and status >= 300):
            log.info(
                "webhook %s: delivery %s (%s) got %s", delivery.webhook_id, delivery.id, delivery.event, error or status
            )
    return len(due)


def attempt(delivery: Due, policy: DeliveryPolicy, client: Poster) -> tuple[int | None, str | None]:
    """Post one delivery: the answer's status, or None and why there was none."""
    body = delivery.body.encode()
    headers = {
        "Content-Type": "application/json",
        "User-Agent": USER_AGENT,
        "X-Curvefm-Event": delivery.event,
        "X-Curvefm-Delivery": delivery.id,
        SIGNATURE_HEADER: signature(delivery.secret, int(time.time()), body),
    }
    try:
        check_resolved(delivery.url, policy.allow_private, policy.allow_private_setting)
        response = client.post(delivery.url, content=body, headers=headers)
    except CurvefmError as exc:
        return None, exc.message[:MAX_ERROR_LENGTH]
    except httpx.HTTPError as exc:
        return None, f"{type(exc).__name__}: {exc}"[:MAX_ERROR_LENGTH]
    error = None if 200 <= response.status_code < 300 else f"the receiver answered {response.status_code}"
    return response.status_code, error


def start_delivery(outbox: Webhooks, policy: DeliveryPolicy, poll_s: float) -> threading.Event:
    """Deliver in a daemon thread, looking for due deliveries every ``poll_s``; set the event to stop."""
    stop = threading.Event()

    def loop() -> None:
        with httpx.Client(timeout=policy.timeout_s, follow_redirects=False, trust_env=False) as client:
            while not stop.is_set():
                try:
                    busy = deliver_due(outbox, policy, client)
                except Exception:  # a database that does not answer must not end the loop
                    log.exception("delivering webhooks failed; trying again in %.1f s", poll_s)
                    busy = 0
                if busy < BATCH and stop.wait(poll_s):
                    return

    threading.Thread(target=loop, name="curvefm-webhooks", daemon=True).start()
    return stop
