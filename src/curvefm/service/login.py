"""The web page's login cookie: an opaque value the service signs and later checks, with nothing stored per login.

The value is ``<payload>.<signature>``, both base64url: the payload is the JSON list ``[user name, binding,
expiry]``, where the binding is :meth:`curvefm.access.Users.token_binding` of the user's token when the
cookie was made, and the signature is HMAC-SHA256 of the payload with the data directory's signing key
(:func:`curvefm.access.signing_key`). So a cookie is good until it expires, its user's token is rotated or the
user is removed, whichever comes first, at every API process of the data directory.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import json
import time

from curvefm.access import User, Users

MAX_COOKIE_CHARS = 512  # far above what we make (about 130): anything longer is refused before it is parsed


class LoginCookies:
    def __init__(self, key: bytes, users: Users, ttl_s: float):
        self.key, self.users, self.ttl_s = key, users, ttl_s

    def issue(self, user: User) -> str:
        """A cookie value for ``user``, good for ``ttl_s`` seconds from now."""
        payload = [user.name, self.users.token_binding(user.name), int(time.time() + self.ttl_s)]
        encoded = _b64encode(json.dumps(payload, separators=(",", ":")).encode())
        return f"{encoded}.{self._sign(encoded)}"

    def verify(self, value: str) -> User | None:
        """The user of a cookie this data directory's key signed, or None (forged, expired, or its user's token
        changed since)."""
        if len(value) > MAX_COOKIE_CHARS or not value.isascii() or value.count(".") != 1:
            return None
        encoded, signature = value.split(".")
        if not hmac.compare_digest(signature, self._sign(encoded)):
            return None
        name, binding, expiry = json.loads(_b64decode(encoded))  # signed, so made by issue()
        if expiry < time.time() or binding != self.users.token_binding(name):
            return None
        return self.users.get(name)

    def _sign(self, encoded: str) -> str:
        return _b64encode(hmac.new(self.key, encoded.encode(), hashlib.sha256).digest())


def _b64encode(data: bytes) -> str:
    return base64.urlsafe_b64encode(data).rstrip(b"=").decode()


def _b64decode(text: str) -> bytes:
    return base64.urlsafe_b64decode(text + "=" * (-len(text) % 4))
