"""The page's session list fetches a page at a time: the newest 50 sessions, the open one, and a "… N more" entry
that lists 50 more."""

from __future__ import annotations

import pytest
from support.lab import Lab
from support.ui import VIEWPORT, open_session

SESSIONS = 53


@pytest.fixture(scope="module")
def lab(module_processes, tmp_path_factory) -> Lab:
    return Lab(module_processes.api(tmp_path_factory.mktemp("session-list") / "data"))


def listed(page) -> list[str]:
    return page.eval_on_selector_all("#session-select option", "(options) => options.map((o) => o.value)")


def test_the_session_list_shows_a_page_and_lists_more_on_demand(lab, browser):
    made = [lab.new_session(name=f"listed {i}") for i in range(SESSIONS)]
    oldest = made[0]
    page = browser.new_context(viewport=VIEWPORT).new_page()
    open_session(page, lab.api.url, oldest, token=lab.api.client.headers["Authorization"].split()[-1])
    first = listed(page)
    # "—", the newest 50, the open session (not among them) and the entry for the 3 not in the page
    assert first[1:51] == made[::-1][:50] and first[51] == oldest and first[-1] == "more-sessions"
    assert "3 more" in page.text_content("#session-select option[value='more-sessions']")
    page.click("#pair-panel summary")  # the Shapes & session panel is folded while a session is open
    page.select_option("#session-select", "more-sessions")
    page.wait_for_function("() => !document.querySelector(\"#session-select option[value='more-sessions']\")")
    assert listed(page)[1:] == made[::-1] and page.input_value("#session-select") == oldest
    page.context.close()
