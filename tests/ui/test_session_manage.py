"""Managing sessions in a real browser (Debian's Chromium through Playwright) against a real server process: the
session list names each entry's shapes, owner and curves and leaves out the collections' member sessions; the search
box finds sessions by name; the open session is renamed, and deleted after the user confirms; a session shared
read-only with the user cannot be renamed or deleted from the page."""

from __future__ import annotations

import pytest
from support.lab import Lab
from support.paths import REPO
from support.ui import VIEWPORT, open_session

ARTIFACTS = REPO / "test-artifacts" / "ui"


@pytest.fixture(scope="module")
def lab(module_processes, tmp_path_factory) -> Lab:
    return Lab(module_processes.api(tmp_path_factory.mktemp("session-manage") / "data"))


LISTED_JS = "[...document.querySelectorAll('#session-select option')].map((o) => o.value).join()"


def listed(page) -> list[str]:
    return page.eval_on_selector_all("#session-select option", "(options) => options.map((o) => o.value)")


def token(client) -> str:
    return client.headers["Authorization"].split()[-1]


def test_sessions_are_found_renamed_and_deleted(lab, browser):
    alpha = lab.new_session(name="alpha pair")
    collection = lab.new_collection(lab.owner, alpha)
    (member,) = lab.owner.get(f"/collections/{collection}").json()["members"]
    beta = lab.new_session(name="beta pair")
    page = browser.new_context(viewport=VIEWPORT).new_page()
    errors = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.on("dialog", lambda dialog: dialog.accept())
    open_session(page, lab.api.url, beta, token=token(lab.owner))
    page.click("#pair-panel summary")

    assert listed(page) == ["", beta, alpha]  # newest change first; the collection's member session is not listed
    assert member["session"] not in listed(page)
    label = page.text_content(f"#session-select option[value='{beta}']")
    assert label.startswith("beta pair · shape → shape · 0 curves · yours · ")

    page.fill("#session-search", "ALPHA")
    # the match, then the open session (listed whatever the search)
    page.wait_for_function(f"(ids) => {LISTED_JS} === ids", arg=",".join(["", alpha, beta]))

    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "20-session-search.png"))
    page.fill("#session-name", "gamma pair")
    page.click("#rename-session")
    page.wait_for_selector("#session-title:has-text('gamma pair')")
    assert lab.owner.get(f"/sessions/{beta}").json()["name"] == "gamma pair"

    page.click("#delete-session")  # confirmed (the dialog handler accepts)
    page.wait_for_function("(alpha) => window.curvefm.ready && window.curvefm.sessionId === alpha", arg=alpha)
    assert lab.owner.get(f"/sessions/{beta}").status_code == 404
    assert beta not in listed(page)
    page.context.close()
    assert not errors, f"uncaught errors in the page: {errors}"


def test_a_dismissed_delete_keeps_the_session(lab, browser):
    kept = lab.new_session(name="kept")
    page = browser.new_context(viewport=VIEWPORT).new_page()
    messages = []
    page.on("dialog", lambda dialog: (messages.append(dialog.message), dialog.dismiss()))
    open_session(page, lab.api.url, kept, token=token(lab.owner))
    page.click("#pair-panel summary")
    page.click("#delete-session")
    assert messages and "kept" in messages[0] and "cannot be undone" in messages[0]
    assert lab.owner.get(f"/sessions/{kept}").status_code == 200
    assert page.evaluate("window.curvefm.sessionId") == kept
    page.context.close()


def test_a_session_shared_read_only_cannot_be_renamed_or_deleted(lab, browser):
    shared = lab.new_session(name="look only", sharing="read")
    page = browser.new_context(viewport=VIEWPORT).new_page()
    open_session(page, lab.api.url, shared, token=token(lab.other))
    page.click("#pair-panel summary")
    assert page.is_disabled("#rename-session") and page.is_disabled("#delete-session")
    assert page.is_disabled("#session-name")
    label = page.text_content(f"#session-select option[value='{shared}']")
    assert "by " in label and "yours" not in label
    page.context.close()
