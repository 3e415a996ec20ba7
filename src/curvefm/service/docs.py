"""The API documentation: ``/openapi.json``, Swagger UI at ``/docs`` and ReDoc at ``/redoc``, for users only.

The pages load Swagger UI and ReDoc from this service (``/vendor/``, see :mod:`curvefm.service.ui`), never from
another host, so they work on a network without internet. They need credentials like the API they describe
(the schema names the installed plugins): the UI's login cookie opens them in a browser, and the pages fetch
``/openapi.json`` with it. A browser without a login is sent to the web UI, which says how to log in, rather than
shown the JSON 401 that other clients get.
"""

from __future__ import annotations

from typing import cast

from fastapi import APIRouter, FastAPI, Request
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.responses import HTMLResponse, JSONResponse, RedirectResponse, Response

from curvefm.errors import Unauthenticated
from curvefm.service.auth import AUTHENTICATED
from curvefm.service.errors import error_response
from curvefm.service.ui import VENDOR_URLS

OPENAPI_URL = "/openapi.json"
TITLE = "curvefm API"
SWAGGER = VENDOR_URLS["swagger-ui-dist"]
SWAGGER_PAGE = bytes(
    get_swagger_ui_html(
        openapi_url=OPENAPI_URL,
        title=TITLE,
        swagger_js_url=f"{SWAGGER}/swagger-ui-bundle.js",
        swagger_css_url=f"{SWAGGER}/swagger-ui.css",
        swagger_favicon_url=f"{SWAGGER}/favicon-32x32.png",
        swagger_ui_parameters={"validatorUrl": None},  # else Swagger UI asks an online validator about the schema
    ).body
)
REDOC_PAGE = bytes(
    get_redoc_html(
        openapi_url=OPENAPI_URL,
        title=TITLE,
        redoc_js_url=f"{VENDOR_URLS['redoc']}/bundles/redoc.standalone.js",
        redoc_favicon_url=f"{SWAGGER}/favicon-32x32.png",
        with_google_fonts=False,
    ).body
)
DOCS_PAGES = {"/docs": SWAGGER_PAGE, "/redoc": REDOC_PAGE}


def documentation_routes() -> APIRouter:
    router = APIRouter(dependencies=AUTHENTICATED, include_in_schema=False)

    @router.get(OPENAPI_URL)
    def openapi(request: Request) -> JSONResponse:
        return JSONResponse(request.app.openapi())

    @router.get("/docs")
    def swagger_ui() -> HTMLResponse:
        return HTMLResponse(SWAGGER_PAGE)

    @router.get("/redoc")
    def redoc() -> HTMLResponse:
        return HTMLResponse(REDOC_PAGE)

    return router


def install_docs_login(app: FastAPI) -> None:
    """A browser (``Accept: text/html``) without a login that opens ``/docs`` or ``/redoc`` goes to the web UI's
    login page (303 to ``/``); every other request without one keeps the JSON 401."""

    async def unauthenticated(request: Request, exc: Exception) -> Response:
        if request.url.path in DOCS_PAGES and "text/html" in request.headers.get("accept", ""):
            return RedirectResponse("/", status_code=303)
        return error_response(cast(Unauthenticated, exc))

    app.add_exception_handler(Unauthenticated, unauthenticated)
