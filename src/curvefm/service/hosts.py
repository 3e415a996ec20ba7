"""The Host check: a request whose ``Host`` is not an allowed host answers 400 with an error body, so a page on a
foreign domain that resolves to this server (DNS rebinding) cannot read or drive the API."""

from __future__ import annotations

import re

from curvefm.errors import InvalidInput, shown
from curvefm.service.errors import error_response
from curvefm.service.settings import ANY_HOST, env_name, normal_host


class HostCheck:
    """Answers 400 with an error body to a request whose Host is not in ``allowed`` (``*``: any host)."""

    def __init__(self, app, allowed: tuple[str, ...]):
        self.app = app
        self.allowed = None if ANY_HOST in allowed else frozenset(allowed)

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] == "http" and self.allowed is not None:
            host = request_host(scope)
            if host not in self.allowed:
                await error_response(foreign_host(host))(scope, receive, send)
                return
        await self.app(scope, receive, send)


HOST_HEADER = re.compile(r"(?:\[(?P<ipv6>[0-9A-Fa-f:.]+)\]|(?P<name>[A-Za-z0-9._-]+))(?::[0-9]{1,5})?")
"""``name[:port]`` or ``[IPv6][:port]``: anything else (``host:abc``, ``a:1@b``) is no host."""


def request_host(scope) -> str:
    """The Host header's name, without the port, normalised as the allowed hosts are; '' when absent or
    malformed."""
    value = dict(scope["headers"]).get(b"host", b"").decode("latin-1")
    match = HOST_HEADER.fullmatch(value)
    if match is None:
        return ""
    return normal_host(match["ipv6"] or match["name"])


def foreign_host(host: str) -> InvalidInput:
    variable = env_name("allowed_hosts")
    if not host:
        return InvalidInput(
            f"the request has no Host header of the form NAME[:PORT]; the allowed hosts are set by {variable}"
        )
    return InvalidInput(
        f"host '{shown(host)}' is not served here; a server's admin adds it with --allowed-hosts or {variable}"
    )
