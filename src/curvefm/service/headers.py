"""Security headers on every response (API and UI), as ASGI middleware around the whole app.

Every response says ``nosniff``, may not be framed and sends no referrer; the Content-Security-Policy lets the
UI and the API documentation (``/docs``, ``/redoc``) load scripts, styles and data from this origin only. Inline
scripts (the UI's import map, the documentation pages' start-up scripts) are allowed by their hashes, computed from
the pages when the app starts.
"""

from __future__ import annotations

import base64
import hashlib
import re
from collections.abc import Iterable
from pathlib import Path

_INLINE_SCRIPT = re.compile(rb"<script(?![^>]*\bsrc=)[^>]*>(.*?)</script>", re.DOTALL)
FIXED_HEADERS = {
    "x-content-type-options": "nosniff",
    "x-frame-options": "DENY",
    "referrer-policy": "no-referrer",
}
DOCS_PATHS = ("/docs", "/redoc")
API_CSP = "default-src 'none'; frame-ancestors 'none'"
"""For answers that are data, never a page (e.g. internal errors, answered outside the middleware)."""


def ui_csp(index_html: Path) -> str:
    """The UI's policy: this origin only; inline scripts of ``index_html`` by hash; images also from ``blob:``
    (a texture image the user picks) and ``data:`` (the empty favicon)."""
    return (
        f"default-src 'self'; script-src {_scripts(index_html.read_bytes())}; style-src 'self'; "
        "img-src 'self' data: blob:; connect-src 'self'; object-src 'none'; base-uri 'none'; "
        "form-action 'self'; frame-ancestors 'none'"
    )


def docs_csp(pages: Iterable[bytes]) -> str:
    """The policy of ``/docs`` and ``/redoc``: this origin only, their inline start-up script by hash; inline
    styles, which Swagger UI and ReDoc set on their elements, and ``blob:`` workers (ReDoc's search)."""
    return (
        f"default-src 'self'; script-src {_scripts(*pages)}; style-src 'self' 'unsafe-inline'; "
        "img-src 'self' data:; worker-src 'self' blob:; connect-src 'self'; object-src 'none'; base-uri 'none'; "
        "form-action 'self'; frame-ancestors 'none'"
    )


def _scripts(*pages: bytes) -> str:
    """``'self'`` and the hash of every inline script of ``pages``."""
    hashes = {
        "'sha256-" + base64.b64encode(hashlib.sha256(body).digest()).decode() + "'"
        for page in pages
        for body in _INLINE_SCRIPT.findall(page)
    }
    return " ".join(["'self'", *sorted(hashes)])


def security_headers(path: str, csp: str, docs_csp: str) -> dict[str, str]:
    policy = docs_csp if path in DOCS_PATHS else csp
    return {**FIXED_HEADERS, "content-security-policy": policy}


class SecurityHeaders:
    """Adds :func:`security_headers` to every HTTP response (replacing any of those names already set)."""

    def __init__(self, app, csp: str, docs_csp: str):
        self.app, self.csp, self.docs_csp = app, csp, docs_csp

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = security_headers(scope["path"], self.csp, self.docs_csp)
        added = [(name.encode(), value.encode()) for name, value in headers.items()]
        names = {name for name, _ in added}

        async def send_with_headers(message) -> None:
            if message["type"] == "http.response.start":
                kept = [(n, v) for n, v in message.get("headers", []) if n.lower() not in names]
                message = {**message, "headers": kept + added}
            await send(message)

        await self.app(scope, receive, send_with_headers)
