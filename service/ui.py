"""The web UI: static files from ``static/`` at ``/``, three.js from npm at ``/vendor/three/``.

three.js is not committed: ``npm install`` (run by ``scripts/setup.sh``) puts the version pinned in
``package.json`` into ``node_modules/three`` at the repository root; ``CURVEFM_THREE_DIR`` points elsewhere
(e.g. in an image that copied the package). The page imports it through an import map, with no build step.
"""

from __future__ import annotations

import logging
import os
from functools import cache
from pathlib import Path

from fastapi import FastAPI
from fastapi.responses import JSONResponse
from fastapi.staticfiles import StaticFiles

STATIC_DIR = Path(__file__).parent / "static"
INDEX_HTML = STATIC_DIR / "index.html"
VENDOR_URL = "/vendor/three"
REPO_THREE_DIR = Path(__file__).resolve().parents[1] / "node_modules" / "three"
log = logging.getLogger("curvefm.service")


def three_dir() -> Path:
    """Where the three.js package is: ``CURVEFM_THREE_DIR``, else ``node_modules/three`` of the checkout."""
    return Path(os.environ.get("CURVEFM_THREE_DIR") or REPO_THREE_DIR)


@cache
def _ui_top_names() -> frozenset[str]:
    return frozenset([path.name for path in STATIC_DIR.iterdir()] + [VENDOR_URL.split("/")[1]])


def is_ui_path(path: str) -> bool:
    """Whether ``path`` is the page or one of its static files (which need no token and are not limited)."""
    return path == "/" or path.split("/", 2)[1] in _ui_top_names()


def mount_ui(app: FastAPI) -> None:
    """Add the UI to ``app``: call it after the API routers (the catch-all ``/`` mount comes last)."""

    three = three_dir()
    if (three / "build" / "three.module.js").is_file():
        app.mount(VENDOR_URL, StaticFiles(directory=three), name="vendor-three")
    else:
        message = (
            "three.js is not installed on the server: run `npm install` in the repository root "
            "(scripts/setup.sh does) or set CURVEFM_THREE_DIR to an installed 'three' package"
        )
        log.warning("%s (looked in %s)", message, three)  # the path goes to the log, not to the page

        @app.get(VENDOR_URL + "/{path:path}", include_in_schema=False)
        def three_missing(path: str) -> JSONResponse:
            return JSONResponse({"error": "not_found", "detail": message}, status_code=404)

    app.mount("/", StaticFiles(directory=STATIC_DIR, html=True), name="ui")
