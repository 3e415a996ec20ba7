"""The web UI: static files from ``static/`` at ``/``, and the browser packages from npm under ``/vendor/``:
three.js (``/vendor/three/``) for the UI, Swagger UI and ReDoc for ``/docs`` and ``/redoc``.

The npm packages are not committed. A wheel carries the files the pages load, copied at build time from the
versions ``package-lock.json`` pins (``build_vendor.py``), in ``curvefm/service/vendor/``; a checkout serves its
``node_modules`` (``npm install``, run by ``scripts/setup.sh``); ``CURVEFM_THREE_DIR`` points at another three.js
package. The page imports three.js through an import map, with no build step.
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
PACKAGED_VENDOR_DIR = Path(__file__).parent / "vendor"
"""Where a wheel carries the npm files (absent in a checkout)."""
REPO_NODE_MODULES = Path(__file__).resolve().parents[3] / "node_modules"
VENDOR_URLS = {"three": "/vendor/three", "swagger-ui-dist": "/vendor/swagger-ui", "redoc": "/vendor/redoc"}
"""Where each npm package is served."""
VENDOR_ENTRY = {
    "three": "build/three.module.js",
    "swagger-ui-dist": "swagger-ui-bundle.js",
    "redoc": "bundles/redoc.standalone.js",
}
"""A file each package must have to be served."""
METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE")
log = logging.getLogger("curvefm.service")


def vendor_dir(package: str) -> Path:
    """Where the npm ``package`` is: for three.js ``CURVEFM_THREE_DIR`` if set; else the wheel's copy, else the
    checkout's ``node_modules``."""
    if package == "three" and os.environ.get("CURVEFM_THREE_DIR"):
        return Path(os.environ["CURVEFM_THREE_DIR"])
    packaged = PACKAGED_VENDOR_DIR / package
    return packaged if (packaged / VENDOR_ENTRY[package]).is_file() else REPO_NODE_MODULES / package


@cache
def _ui_top_names() -> frozenset[str]:
    return frozenset([path.name for path in STATIC_DIR.iterdir()] + ["vendor"])


def is_ui_path(path: str) -> bool:
    """Whether ``path`` is the page or one of its static files (which need no token and are not limited)."""
    return path == "/" or path.split("/", 2)[1] in _ui_top_names()


def mount_ui(app: FastAPI) -> None:
    """Add the UI and the npm packages to ``app``: call it after the API routers (the catch-all ``/`` mount comes
    last)."""
    for package, url in VENDOR_URLS.items():
        _mount_vendor(app, package, url)
    app.router.routes.append(UiMount(app.router.routes))


def _mount_vendor(app: FastAPI, package: str, url: str) -> None:
    folder = vendor_dir(package)
    if (folder / VENDOR_ENTRY[package]).is_file():
        app.mount(url, StaticFiles(directory=folder), name=f"vendor-{package}")
        return
    message = (
        f"the npm package '{package}' is not installed on the server: install a curvefm wheel (it carries it), or "
        "run `npm install` in the repository root (scripts/setup.sh does)"
        + (", or set CURVEFM_THREE_DIR to an installed 'three' package" if package == "three" else "")
    )
    log.warning("%s (looked in %s)", message, folder)  # the path goes to the log, not to the page

    @app.get(url + "/{path:path}", include_in_schema=False, name=f"missing-{package}")
    def vendor_missing(path: str) -> JSONResponse:
        return JSONResponse({"error": "not_found", "detail": message}, status_code=404)


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
