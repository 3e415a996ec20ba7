"""Guided clicking of a collection's template curves in a real browser (Debian's Chromium through Playwright)
against a real ``python -m curvefm.service`` process: a collection with two template curves on a small ellipsoid and
one member (a stretched copy, same vertex ids), made through the API; in the page the member is opened, its first
template curve answered by real clicks on the target, another skipped, and the collection run as a batch whose
archive is downloaded. Screenshots go to ``test-artifacts/ui/``."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import REPO
from shapes import ellipsoid, off_bytes
from ui_helpers import (
    VIEWPORT,
    canvas_pixels,
    changed_fraction,
    endpoint_pairs,
    next_frames,
    open_session,
    pickable_vertices,
    sample_count,
)

ARTIFACTS = REPO / "test-artifacts" / "ui"
K = 20
TEMPLATE_CURVES = [{"name": "spine", "waypoints": [10, 500]}, {"name": "tail", "waypoints": [30, 900]}]


@pytest.fixture(scope="module")
def served(module_processes, tmp_path_factory):
    """A server (jobs in-process) with a collection c of two template curves and one member m1 whose bases are ready."""
    api = module_processes.api(tmp_path_factory.mktemp("ui-collections") / "data")
    shapes = []
    for radii in ((1.0, 0.7, 0.5), (1.1, 0.6, 0.55)):
        upload = api.client.post("/shapes", files={"file": ("ellipsoid.off", off_bytes(ellipsoid(radii=radii)))})
        shapes.append(upload.raise_for_status().json()["id"])
        job = api.client.post(f"/shapes/{shapes[-1]}/bases", json={"k": K}).raise_for_status().json()
        assert api.wait_job(job["id"])["state"] == "finished"
    body = {"name": "ellipsoids", "template": shapes[0], "curves": TEMPLATE_CURVES, "members": [shapes[1]], "k": K}
    view = api.client.post("/collections", json=body).raise_for_status().json()
    assert [m["basis"] for m in view["members"]] == ["ready"]
    return api, view


def member_status(api, collection_id: str) -> dict:
    (member,) = api.client.get(f"/collections/{collection_id}").raise_for_status().json()["members"]
    return member


def current(page):
    return page.evaluate("window.curvefm.guide && window.curvefm.guide.current")


def wait_for_current(page, curve_id) -> None:
    page.wait_for_function(
        "(id) => window.curvefm.ready && window.curvefm.guide && window.curvefm.guide.current === id", arg=curve_id
    )


def test_a_member_is_clicked_curve_by_curve_skipped_and_run(browser, served):
    api, view = served
    collection_id, (member,) = view["collection"]["id"], view["members"]
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    page = context.new_page()
    errors = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    open_session(page, api.url, member["session"], token=api.token)

    page.click("#collections-panel summary")
    page.select_option("#collection-select", collection_id)
    page.click('#member-list li[data-member-id="m1"] button[data-action="open"]')
    wait_for_current(page, "t1")
    assert page.text_content("#guide-prompt").startswith("t1 'spine': click its start on the member")
    assert page.text_content("#hint") == page.text_content("#guide-prompt")
    assert "0/2 curves" in page.text_content('#member-list li[data-member-id="m1"]')
    page.click("#guide-skip")
    wait_for_current(page, "t2")
    assert page.get_attribute("#template-curves li.current", "data-template-curve") == "t2"
    page.click("#guide-previous")
    wait_for_current(page, "t1")

    page.uncheck("#show-curves")  # compare the carried texture alone
    before = canvas_pixels(page, "target")
    ((start, end),) = endpoint_pairs(pickable_vertices(page), 1, seed=2)
    samples = sample_count(page)
    page.mouse.click(*start["target"])
    next_frames(page)
    assert page.text_content("#guide-prompt").startswith("t1 'spine': click its end on the member")
    page.mouse.click(*end["target"])
    page.wait_for_function("(n) => window.curvefmStats.samples.length > n", arg=samples, timeout=30_000)
    assert page.evaluate("window.curvefmStats.last.kind") == "answer"
    changed = changed_fraction(before, canvas_pixels(page, "target"))
    assert changed > 0.003, f"the member's texture barely changed ({changed:.4f}) after answering t1"
    page.check("#show-curves")
    wait_for_current(page, "t2")  # the next unanswered template curve
    page.wait_for_selector('#template-curves li[data-template-curve="t1"].answered')
    page.wait_for_selector('#member-list li[data-member-id="m1"]:has-text("1/2 curves")')
    assert page.text_content("#guide-prompt").startswith("t2 'tail': click its start")
    next_frames(page)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "10-collection-member-t1-answered.png"))

    status = member_status(api, collection_id)
    assert (status["curves_done"], status["curves_total"], status["extra_curves"]) == (1, 2, 0)
    (curve,) = api.client.get(f"/sessions/{member['session']}").json()["curves"]
    assert curve["spec"]["template_curve"] == "t1" and curve["spec"]["target"] == [start["id"], end["id"]]
    assert "→ t1" in page.text_content(f'#curve-list li[data-curve-id="{curve["id"]}"]')

    page.click("#guide-skip")  # t1 is answered: nothing is left to answer
    page.wait_for_function("() => window.curvefm.guide.current === null")
    assert page.text_content("#guide-prompt").startswith("No template curve is current")
    page.reload()  # the URL names the member: it opens guided again, at its first unanswered curve
    wait_for_current(page, "t2")

    page.select_option("#run-converter-select", "nearest-neighbor")
    page.click("#run-all")
    page.wait_for_selector('#run-downloads a[download="archive.npz"]', timeout=60_000)
    assert page.locator("#run-progress .progress-row.ok").count() == 1
    page.wait_for_selector('#member-list li[data-member-id="m1"]:has-text("run finished")')
    with page.expect_download() as download:
        page.click('#run-downloads a[download="archive.npz"]')
    archive = np.load(download.value.path())
    live = api.client.get(f"/sessions/{member['session']}/map").json()
    np.testing.assert_allclose(archive["m1/C_template_to_member"], live["C_source_to_target"], atol=1e-12)
    context.close()
    assert not errors, f"uncaught errors in the page: {errors}"
