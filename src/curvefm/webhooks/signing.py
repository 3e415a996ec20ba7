"""The signature a delivery carries, as Stripe's and Slack's webhooks do: HMAC-SHA256 with the webhook's secret
over ``<timestamp>.<body>``, sent as ``X-Curvefm-Signature: t=<timestamp>,v1=<hex digest>``. The timestamp is
signed too, so a receiver that refuses old timestamps refuses a replayed delivery."""

from __future__ import annotations

import hashlib
import hmac
import secrets

SIGNATURE_HEADER = "X-Curvefm-Signature"
SCHEME = "v1"
SECRET_PREFIX = "whsec_"


def new_secret() -> str:
    """A secret for a new webhook (256 random bits)."""
    return SECRET_PREFIX + secrets.token_urlsafe(32)


def digest(secret: str, timestamp: int, body: bytes) -> str:
    return hmac.new(secret.encode(), str(timestamp).encode() + b"." + body, hashlib.sha256).hexdigest()


def signature(secret: str, timestamp: int, body: bytes) -> str:
    """The value of :data:`SIGNATURE_HEADER` for ``body`` sent at ``timestamp`` (UNIX seconds)."""
    return f"t={timestamp},{SCHEME}={digest(secret, timestamp, body)}"


def verify(secret: str, header: str, body: bytes, now: float, tolerance_s: float = 300.0) -> bool:
    """Whether ``header`` signs ``body`` with ``secret`` at a time within ``tolerance_s`` of ``now`` (what a
    receiver checks)."""
    fields = dict(part.split("=", 1) for part in header.split(",") if "=" in part)
    try:
        timestamp = int(fields["t"])
    except (KeyError, ValueError):
        return False
    if abs(now - timestamp) > tolerance_s:
        return False
    return hmac.compare_digest(fields.get(SCHEME, ""), digest(secret, timestamp, body))
