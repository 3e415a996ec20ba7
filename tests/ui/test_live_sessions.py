"""Live shared sessions in real browsers (Debian's Chromium through Playwright): two users, each in a browser context
of their own, have one session (shared editable) open through two API processes that share a data directory and
Redis. A curve clicked on one page shows on the other without a reload, each page names the other user, and an
edit from a page that missed a change is refused (409) and the page brought up to date."""

from __future__ import annotations

import uuid

import pytest
from support.redis_servers import delete_prefix
from support.ui import VIEWPORT, click_curve, endpoint_pairs, open_session, pickable_vertices

K = 30
CURVES_JS = "() => [...document.querySelectorAll('#curve-list li[data-curve-id]')].map((li) => li.dataset.curveId)"


@pytest.fixture(scope="module")
def replicas(module_processes, tmp_path_factory, redis_url):
    """Two API processes on one data directory and one Redis (with a worker), the demo shapes with their bases."""
    folder = tmp_path_factory.mktemp("live-ui")
    prefix = f"cfmtest-{uuid.uuid4().hex[:10]}-"
    env = {"CURVEFM_QUEUE_PREFIX": prefix, "CURVEFM_EVENTS_POLL": "0.3"}
    first = module_processes.api(folder / "data", redis_url, env=env)
    module_processes.worker(redis_url, prefix, "live-ui")
    first.shapes, _ = first.demo_pair(folder, K)
    second = module_processes.api(folder / "data", redis_url, env=env)
    yield first, second
    delete_prefix(redis_url, prefix)


def token(client) -> str:
    return client.headers["Authorization"].split()[-1]


def curves_shown(page) -> list[str]:
    return page.evaluate(CURVES_JS)


def wait_for_curves(page, ids: list[str]) -> None:
    page.wait_for_function(f"(ids) => ({CURVES_JS})().join() === ids.join()", arg=ids, timeout=60_000)


def opened(browser, url: str, session: str, client, errors: list[str], block_events: bool = False):
    context = browser.new_context(viewport=VIEWPORT)
    if block_events:  # a page that misses every change (a dropped connection, a proxy that buffers)
        context.route("**/sessions/*/events", lambda route: route.abort())
    page = context.new_page()
    page.on("pageerror", lambda error: errors.append(str(error)))
    open_session(page, url, session, token=token(client))
    return page


def test_two_users_on_two_processes_see_each_others_changes_and_each_other(replicas, browser):
    first, second = replicas
    owner, bob = first.client, second.client_for("bob")
    body = {"source": first.shapes[0], "target": first.shapes[1], "k": K, "sharing": "edit", "name": "shared"}
    session = owner.post("/sessions", json=body).raise_for_status().json()["id"]
    errors: list[str] = []
    owners = opened(browser, first.url, session, owner, errors)
    bobs = opened(browser, second.url, session, bob, errors)

    # presence: each page names the other user (and not its own)
    owners.wait_for_selector("#viewers:has-text('bob')", timeout=60_000)
    bobs.wait_for_selector("#viewers:has-text('tester')", timeout=60_000)
    assert "tester" not in owners.text_content("#viewers") and "bob" not in bobs.text_content("#viewers")

    # a curve clicked on the owner's page (first process) shows on bob's (second process) without a reload
    (pair,) = endpoint_pairs(pickable_vertices(owners), 1)
    click_curve(owners, list(pair))
    wait_for_curves(bobs, ["c1"])
    bobs.wait_for_function("() => window.curvefm.tubeCount('target') === 1")
    bobs.wait_for_selector("#status-line:has-text('revision 1')")

    # bob's removal on his page shows on the owner's
    bobs.click("#curve-list li[data-curve-id='c1'] button[data-action='delete']")
    wait_for_curves(owners, [])

    # bob closes his page: the owner's page stops naming him
    bobs.context.close()
    owners.wait_for_selector("#viewers", state="hidden", timeout=60_000)
    owners.context.close()
    assert not errors, f"uncaught errors in the pages: {errors}"


def test_an_edit_from_a_page_that_missed_a_change_is_refused_and_the_page_resyncs(replicas, browser):
    first, second = replicas
    owner, bob = first.client, second.client_for("bob")
    body = {"source": first.shapes[0], "target": first.shapes[1], "k": K, "sharing": "edit"}
    session = owner.post("/sessions", json=body).raise_for_status().json()["id"]
    curve = {"source": [0, 2000], "target": [0, 2000]}
    owner.post(f"/sessions/{session}/curves", json=curve).raise_for_status()
    errors: list[str] = []
    deaf = opened(browser, second.url, session, bob, errors, block_events=True)
    assert curves_shown(deaf) == ["c1"]
    owner.post(f"/sessions/{session}/curves", json={"source": [100, 3000], "target": [100, 3000]}).raise_for_status()

    deaf.click("#curve-list li[data-curve-id='c1'] button[data-action='delete']")  # based on revision 1, now 2
    deaf.wait_for_selector(".toast.error:has-text('not 1 as this edit expected')", timeout=60_000)
    deaf.wait_for_selector(".toast:has-text('changed elsewhere')", timeout=60_000)
    wait_for_curves(deaf, ["c1", "c2"])
    deaf.wait_for_selector("#status-line:has-text('revision 2')")
    assert [c["id"] for c in owner.get(f"/sessions/{session}").json()["curves"]] == ["c1", "c2"]  # nothing deleted
    deaf.context.close()
    assert not errors, f"uncaught errors in the pages: {errors}"
