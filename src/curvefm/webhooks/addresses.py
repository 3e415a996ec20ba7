"""Which URLs a webhook may post to. A server that posts where its users say can be made to reach what only it
can reach (SSRF: a metadata service, a database's HTTP port, the API itself), so unless the operator allows it
(``CURVEFM_WEBHOOK_ALLOW_PRIVATE``) an address that is loopback, private, link-local, multicast, reserved or
unspecified is refused: a literal one when the webhook is registered, a name that resolves to one at every
delivery (a name's addresses may change after it was registered)."""

from __future__ import annotations

import ipaddress
import socket
from urllib.parse import urlsplit

from curvefm.errors import InvalidInput

SCHEMES = ("http", "https")
LOCAL_NAMES = ("localhost", "localhost.localdomain")
MAX_URL_LENGTH = 2000


def checked_url(url: str, allow_private: bool, setting: str) -> str:
    """``url`` when a webhook may be registered with it; :class:`InvalidInput` saying why not."""
    parts = urlsplit(url.strip())
    if len(url) > MAX_URL_LENGTH:
        raise InvalidInput(f"a webhook URL has at most {MAX_URL_LENGTH} characters")
    if parts.scheme not in SCHEMES or not parts.hostname:
        raise InvalidInput("a webhook URL is http:// or https:// with a host name, e.g. https://lab.example/hook")
    if parts.username or parts.password:
        raise InvalidInput("a webhook URL carries no user name or password; the signature authenticates curvefm")
    try:
        parts.port  # noqa: B018 (raises for a port that is not a number in range)
    except ValueError:
        raise InvalidInput("the webhook URL's port is not a number from 1 to 65535") from None
    host = parts.hostname.rstrip(".").lower()
    if not allow_private and (host in LOCAL_NAMES or host.endswith(".localhost") or _private_literal(host)):
        raise InvalidInput(_refusal(host, setting))
    return url.strip()


def check_resolved(url: str, allow_private: bool, setting: str) -> None:
    """Before a delivery: :class:`InvalidInput` when the URL's host resolves to an address it may not reach (or
    does not resolve)."""
    if allow_private:
        return
    parts = urlsplit(url)
    host = parts.hostname or ""
    try:
        infos = socket.getaddrinfo(host, parts.port or 443, type=socket.SOCK_STREAM)
    except OSError as exc:
        raise InvalidInput(f"the webhook's host does not resolve ({exc.strerror or exc})") from None
    for info in infos:
        if not _public(ipaddress.ip_address(info[4][0])):
            raise InvalidInput(_refusal(host, setting))


def _private_literal(host: str) -> bool:
    try:
        return not _public(ipaddress.ip_address(host))
    except ValueError:  # a name, checked when it is resolved
        return False


def _public(address: ipaddress.IPv4Address | ipaddress.IPv6Address) -> bool:
    mapped = getattr(address, "ipv4_mapped", None)
    return (mapped or address).is_global and not (mapped or address).is_multicast


def _refusal(host: str, setting: str) -> str:
    return (
        f"webhook host '{host[:100]}' is a loopback, private or otherwise internal address, which webhooks may not "
        f"reach here (the operator allows them with {setting}=true)"
    )
