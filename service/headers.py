"""Security headers on every response (API and UI), as ASGI middleware around the whole app.

Every response says ``nosniff``, may not be framed and sends no referrer; the Content-Security-Policy lets the
UI load scripts, styles and data from this origin only. The UI's one inline script, its import map, is allowed
by its hash, computed from ``index.html`` when the app starts.
"""

from __future__ import annotations

import base64
import hashlib
import re
from pathlib import Path

_INLINE_SCRIPT = re.compile(rb"<script(?![^>]*\bsrc=)[^>]*>(.*?)</script>", re.DOTALL)
FIXED_HEADERS = {
    "x-content-type-options": "nosniff",
    "x-frame-options": "DENY",
    "referrer-policy": "no-referrer",
}
# /docs is FastAPI's Swagger UI: its script, styles and logo come from a CDN, started by an inline script.
DOCS_CSP = (
    "default-src 'self'; script-src 'self' 'unsafe-inline' https://cdn.jsdelivr.net; "
    "style-src 'self' 'unsafe-inline' https://cdn.jsdelivr.net; img-src 'self' data: https://fastapi.tiangolo.com; "
    "object-src 'none'; base-uri 'none'; frame-ancestors 'none'"
)
DOCS_PATHS = ("/docs", "/redoc")
API_CSP = "default-src 'none'; frame-ancestors 'none'"
"""For answers that are data, never a page (e.g. internal errors, answered outside the middleware)."""


def ui_csp(index_html: Path) -> str:
    """The UI's policy: this origin only; inline scripts of ``index_html`` by hash; images also from ``blob:``
    (a texture image the user picks) and ``data:`` (the empty favicon)."""
    sources = ["'self'"] + [
        "'sha256-" + base64.b64encode(hashlib.sha256(body).digest()).decode() + "'"
        for body in _INLINE_SCRIPT.findall(index_html.read_bytes())
    ]
    return (
        f"default-src 'self'; script-src {' '.join(sources)}; style-src 'self'; "
        "img-src 'self' data: blob:; connect-src 'self'; object-src 'none'; base-uri 'none'; "
        "form-action 'self'; frame-ancestors 'none'"
    )


def security_headers(path: str, csp: str) -> dict[str, str]:
    policy = DOCS_CSP if path.startswith(DOCS_PATHS) else csp
    return {**FIXED_HEADERS, "content-security-policy": policy}


class SecurityHeaders:
    """Adds :func:`security_headers` to every HTTP response (replacing any of those names already set)."""

    def __init__(self, app, csp: str):
        self.app, self.csp = app, csp

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        added = [(name.encode(), value.encode()) for name, value in security_headers(scope["path"], self.csp).items()]
        names = {name for name, _ in added}

        async def send_with_headers(message) -> None:
            if message["type"] == "http.response.start":
                kept = [(n, v) for n, v in message.get("headers", []) if n.lower() not in names]
                message = {**message, "headers": kept + added}
            await send(message)

        await self.app(scope, receive, send_with_headers)
