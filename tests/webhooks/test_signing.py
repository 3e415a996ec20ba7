"""The signature scheme: HMAC-SHA256 over ``<t>.<body>``, checked against a digest computed here, and refused
for another body, another secret or an old timestamp."""

from __future__ import annotations

import hashlib
import hmac

from curvefm.webhooks import new_secret, signature, verify


def test_the_signature_is_the_documented_hmac():
    secret, body, at = new_secret(), b'{"event":"run.ended"}', 1_800_000_000
    header = signature(secret, at, body)
    expected = hmac.new(secret.encode(), b"1800000000." + body, hashlib.sha256).hexdigest()
    assert header == f"t=1800000000,v1={expected}"
    assert verify(secret, header, body, now=at + 10)
    assert not verify(secret, header, body + b" ", now=at)
    assert not verify(new_secret(), header, body, now=at)
    assert not verify(secret, header, body, now=at + 301)  # a replay, later
    assert not verify(secret, "v1=abc", body, now=at)
    assert new_secret() != new_secret()
