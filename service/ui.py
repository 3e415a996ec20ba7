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
from starlette.routing import BaseRoute, Match, Mount
from starlette.types import Scope

STATIC_DIR = Path(__file__).parent / "static"
INDEX_HTML = STATIC_DIR / "index.html"
VENDOR_URL = "/vendor/three"
METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE")
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

    app.router.routes.append(UiMount(app.router.routes))


class UiMount(Mount):
    """The UI's catch-all mount at ``/``, which leaves every path an API route serves to the API (so that a
    method the API does not serve there answers the API's 405 with its ``Allow``, not the static files')."""

    def __init__(self, routes: list[BaseRoute]):
        super().__init__("/", app=StaticFiles(directory=STATIC_DIR, html=True), name="ui")
        self.api_routes = list(routes)

    def matches(self, scope: Scope) -> tuple[Match, Scope]:
        if scope["type"] == "http" and api_methods(self.api_routes, scope):
            return Match.NONE, {}
        return super().matches(scope)


def api_methods(routes: list[BaseRoute], scope: Scope) -> list[str]:
    """The methods the API's routes among ``routes`` serve at the path of ``scope`` (none: not an API path).
    Mounts (static files) are not the API."""
    api = [route for route in routes if not isinstance(route, Mount)]
    return [method for method in METHODS if any(_serves(route, scope, method) for route in api)]


def _serves(route: BaseRoute, scope: Scope, method: str) -> bool:
    return route.matches({**scope, "method": method})[0] == Match.FULL
