"""The API documentation works on a network without internet: ``/docs`` (Swagger UI) and ``/redoc`` (ReDoc) load
their scripts from this service, every page it serves names no other host, and the pages render in Chromium
under their Content-Security-Policy. They need credentials, like the schema they show."""

from __future__ import annotations

import re
from urllib.parse import urljoin, urlsplit

import pytest
from support.ui import PageWatch

PAGES = ("/", "/docs", "/redoc")
REDOC_LOGO = "img-src https://cdn.redoc.ly/redoc/logo-mini.svg"
"""ReDoc's bundle always draws its maker's logo from their server: the policy blocks it and ReDoc then hides it
(its onError); it is the one violation a page may report, and nothing leaves the machine for it."""
_REFERENCE = re.compile(r"""(?:\bsrc|\bhref|\baction)\s*=\s*["']([^"']*)["']|url\(\s*["']?([^"')]*)""", re.I)


@pytest.fixture(scope="module")
def api(module_processes, tmp_path_factory):
    return module_processes.api(tmp_path_factory.mktemp("docs") / "data")


def references(text: str) -> list[str]:
    """Every address an HTML page or a style sheet refers to (attributes and CSS ``url()``)."""
    return [a or b for a, b in _REFERENCE.findall(text) if (a or b)]


def is_elsewhere(reference: str, origin: str) -> bool:
    absolute = urljoin(origin + "/", reference)
    return urlsplit(absolute).scheme not in ("data", "blob") and not absolute.startswith(origin + "/")


@pytest.mark.parametrize("path", PAGES[1:])
def test_the_documentation_pages_need_credentials(api, path):
    import httpx

    assert httpx.get(api.url + path).status_code == 401
    page = api.client.get(path)
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")


def test_no_served_page_or_style_sheet_names_another_host(api):
    checked = []
    for path in PAGES:
        page = api.client.get(path).raise_for_status()
        assets = [r for r in references(page.text) if r.endswith(".css")]
        for asset in assets:
            sheet = api.client.get(urljoin(api.url + path, asset)).raise_for_status()
            assert not [r for r in references(sheet.text) if is_elsewhere(r, api.url)], asset
        found = references(page.text)
        assert found, f"{path} refers to nothing: the check would prove nothing"
        assert not [r for r in found if is_elsewhere(r, api.url)], (path, found)
        checked += assets
    assert any("swagger-ui" in asset for asset in checked)


def test_the_documentation_renders_offline_under_its_policy(api, browser):
    context = browser.new_context()
    watch = PageWatch(context, api.url)
    page = context.new_page()
    page.goto(f"{api.url}/?token={api.token}")  # the UI trades the token for the login cookie
    page.wait_for_function("() => document.querySelectorAll('#tracer-select option').length > 0", timeout=30_000)

    page.goto(f"{api.url}/docs")
    page.wait_for_function("() => document.querySelectorAll('.opblock').length > 10", timeout=60_000)
    operations = page.locator(".opblock-summary-path").all_inner_texts()
    swagger_violations = watch.violations(page)

    page.goto(f"{api.url}/redoc")
    page.wait_for_function("() => document.querySelectorAll('[data-section-id^=\"tag/\"]').length > 2", timeout=60_000)
    redoc_text = page.inner_text("body")
    logos_shown = page.locator("img[src^='http']").count()  # ReDoc removes its logo once it failed to load
    redoc_violations = watch.violations(page)
    context.close()

    schema = api.client.get("/openapi.json").json()
    assert set(schema["paths"]) <= {text.replace("\u200b", "") for text in operations}
    assert "POST /sessions/{session_id}/refine".split()[1] in redoc_text.replace("\u200b", "")
    assert not swagger_violations and set(redoc_violations) <= {REDOC_LOGO}, (swagger_violations, redoc_violations)
    assert logos_shown == 0
    assert not watch.elsewhere, watch.elsewhere
