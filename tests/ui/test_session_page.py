"""The web UI in a real browser: Debian's Chromium (headless, WebGL through SwiftShader) driven by Playwright
against a real ``python -m curvefm.service --demo`` process. Curves are entered by real mouse clicks on
rendered vertices. Screenshots are written to ``test-artifacts/ui/``.
"""

from __future__ import annotations

import asyncio
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import numpy as np
import pytest
from fastapi import FastAPI
from support.processes import add_user
from support.ui import (
    MIN_CHANGED,
    VIEWPORT,
    canvas_pixels,
    changed_fraction,
    click_curve,
    endpoint_pairs,
    next_frames,
    open_session,
    pickable_vertices,
    refine_in_page,
    screenshot,
)

from curvefm.service.demo import DEMO_SESSION, demo_curves, demo_shapes
from curvefm.service.ui import mount_ui


@pytest.fixture(scope="module")
def demo(module_processes, tmp_path_factory):
    """A demo server whose session is ready (its bases computed and its curves added)."""
    api = module_processes.api(tmp_path_factory.mktemp("ui") / "data", args=("--demo",))
    expected = len(demo_curves(demo_shapes()[0]))
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        response = api.client.get(f"/sessions/{DEMO_SESSION}")
        if response.status_code == 200 and len(response.json()["curves"]) == expected:
            return api
        time.sleep(0.25)
    raise AssertionError(f"the demo session was not ready:\n{api.log.read_text()[-3000:]}")


@pytest.fixture
def page(browser, demo):
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    page = context.new_page()
    errors = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    open_session(page, demo.url, DEMO_SESSION, token=demo.token)
    yield page
    context.close()
    assert not errors, f"uncaught errors in the page: {errors}"


def session(demo) -> dict:
    return demo.client.get(f"/sessions/{DEMO_SESSION}").raise_for_status().json()


def wait_until(condition, what: str, timeout: float = 30) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting until {what}")
        time.sleep(0.1)


def settled_pixels(page, side: str, tries: int = 20) -> np.ndarray:
    """The viewport's pixels once two reads half a second apart agree (the landmark prior lands about a second
    after an edit and repaints the target)."""
    last = canvas_pixels(page, side)
    for _ in range(tries):
        page.wait_for_timeout(500)
        now = canvas_pixels(page, side)
        if changed_fraction(last, now) == 0:
            return now
        last = now
    raise AssertionError(f"the {side} viewport kept changing for {tries} reads")


def shows_in_status_line(page, text: str) -> None:
    page.wait_for_function("(text) => document.querySelector('#status-line').textContent.includes(text)", arg=text)


def test_click_curves_delete_refine_and_download(page, demo):
    screenshot(page, "01-demo-loaded")
    record = session(demo)
    stated = demo.client.get(f"/sessions/{DEMO_SESSION}/solve").raise_for_status().json()
    assert stated["summary"] == "combined; 50 x 50 until curves totalling 6.2 sqrt(area)" and record["k"] == 120
    shows_in_status_line(page, stated["summary"])
    assert page.get_attribute("#status-line", "title") == f"The map: {stated['reason']}."
    target = demo.client.get(f"/shapes/{record['target']}").json()
    source = demo.client.get(f"/shapes/{record['source']}").json()
    known = {curve["id"] for curve in record["curves"]}

    page.uncheck("#show-curves")  # compare the carried texture alone, without the new tube
    candidates = pickable_vertices(page)
    (a1, b1), (a2, b2), (a3, b3) = endpoint_pairs(candidates, 3)
    waypoint = next(c for c in candidates if c["id"] not in (a2["id"], b2["id"]))
    added, samples = [], []
    before = canvas_pixels(page, "target")
    for points in ([a1, b1], [a2, waypoint, b2], [a3, b3]):
        sample = click_curve(page, points)
        samples.append(sample)
        new = [curve for curve in session(demo)["curves"] if curve["id"] not in known]
        assert len(new) == 1, new
        clicked = [point["id"] for point in points]
        assert new[0]["spec"]["source"] == clicked and new[0]["spec"]["target"] == clicked
        assert new[0]["tracer"] == "geodesic" and len(new[0]["path_source"]) >= 2
        assert sample["kind"] == "add" and sample["totalMs"] > 0
        assert sample["requests"] == 1, sample  # the edit's answer carried the texture: no transfer read
        known.add(new[0]["id"])
        added.append(new[0]["id"])
    # One curve may agree with the map already and recolour little; three between far apart points do not.
    changed = changed_fraction(before, settled_pixels(page, "target"))
    assert changed > MIN_CHANGED, f"the target barely changed ({changed:.4f}) after three curves ({samples})"
    page.check("#show-curves")
    next_frames(page)
    screenshot(page, "02-three-curves-clicked")
    assert page.locator("#curve-list li").count() == len(known)
    assert "click→texture" in page.text_content("#status-line")
    shows_in_status_line(page, "combined; 50 x 50 until curves totalling 6.2 sqrt(area)")  # from the edits' answers

    removed = added[0]
    page.click(f'#curve-list li[data-curve-id="{removed}"] button[data-action="delete"]')
    page.wait_for_selector(f'#curve-list li[data-curve-id="{removed}"]', state="detached")
    wait_until(lambda: removed not in {c["id"] for c in session(demo)["curves"]}, f"{removed} is deleted")

    refine_in_page(page)
    screenshot(page, "03-refined-pointwise")

    with page.expect_download() as download:
        page.click('#downloads a[download="map_target_to_source.txt"]')
    refined = session(demo)["revision"]
    assert download.value.suggested_filename == f"demo_demo_nearest-neighbor_r{refined}_map_target_to_source.txt"
    lines = Path(download.value.path()).read_text().split()
    assert len(lines) == target["n_file_vertices"]
    values = np.array(lines, dtype=np.int64)
    assert values.min() >= 0 and values.max() < source["n_file_vertices"]

    with page.expect_download() as download:
        page.click("#download-c")
    C = np.load(download.value.path())
    live = demo.client.get(f"/sessions/{DEMO_SESSION}/map").json()
    assert download.value.suggested_filename == f"demo_demo_live_r{live['revision']}_C_source_to_target.npy"
    np.testing.assert_allclose(C, np.array(live["C_source_to_target"]), rtol=0, atol=1e-12)


def test_the_quality_overlay_tints_the_target_and_follows_every_edit(page, demo):
    def shown_quality() -> dict:
        return settled_quality(page, session(demo)["revision"])

    def served_quality():
        return demo.client.get(f"/sessions/{DEMO_SESSION}/quality").raise_for_status().headers

    first = shown_quality()
    served = served_quality()
    assert first["score"] == pytest.approx(float(served["X-Score"]), rel=1e-5)
    assert "round-trip drift" in page.text_content("#status-line")
    assert page.evaluate("window.curvefm.highlighted('target')") is None  # the overlay is off by default

    page.uncheck("#show-curves")
    before = canvas_pixels(page, "target")
    page.check("#show-quality")
    next_frames(page)
    screenshot(page, "06-quality-overlay")
    changed = changed_fraction(before, canvas_pixels(page, "target"))
    assert changed > MIN_CHANGED, f"the overlay barely tinted the target ({changed:.4f})"
    assert page.evaluate("window.curvefm.highlighted('target')") == int(served["X-Worst-Target"])
    assert page.evaluate("window.curvefm.highlighted('source')") == int(served["X-Worst-Source"])

    ((a, b),) = endpoint_pairs(pickable_vertices(page), 1, seed=3)
    click_curve(page, [a, b])
    after_edit = shown_quality()
    assert after_edit["score"] == pytest.approx(float(served_quality()["X-Score"]), rel=1e-5)
    assert after_edit["score"] != first["score"]
    assert f"{100 * after_edit['score']:.1f}%" in page.text_content("#status-line")

    page.uncheck("#show-quality")
    next_frames(page)
    assert page.evaluate("window.curvefm.highlighted('target')") is None


def settled_quality(page, revision: int) -> dict:
    """The quality the page shows once it is of ``revision`` with its landmark prior landed."""
    page.wait_for_function(
        "(revision) => window.curvefm.quality && window.curvefm.quality.revision === revision"
        " && !window.curvefm.quality.priorPending",
        arg=revision,
    )
    return page.evaluate("window.curvefm.quality")


def test_the_figures_are_marked_until_the_landmark_prior_lands_then_refreshed(page, demo):
    """An edit's prior lands about a second after it: the quality read at once says so, the page greys the drift
    and the overlay's legend ("updating…") and reads again until the figures are the final map's."""
    answers = []  # X-Prior-Pending of every quality answer, in order
    page.on("response", lambda r: "/quality" in r.url and answers.append(r.headers.get("x-prior-pending")))
    page.check("#show-quality")
    ((a, b),) = endpoint_pairs(pickable_vertices(page), 1, seed=7)
    click_curve(page, [a, b])
    page.wait_for_selector("#status-drift.stale:has-text('updating…')")
    assert page.is_visible("#quality-legend.stale:has-text('updating…')")
    screenshot(page, "09-figures-updating")
    revision = session(demo)["revision"]
    shown = settled_quality(page, revision)
    served = demo.client.get(f"/sessions/{DEMO_SESSION}/quality").raise_for_status().headers
    assert served["X-Prior-Pending"] == "false" and shown["score"] == pytest.approx(float(served["X-Score"]), rel=1e-5)
    assert "true" in answers and answers[-1] == "false", answers  # read while pending, then once it landed
    drift = page.locator("#status-drift")
    assert f"{100 * shown['score']:.1f}% of √area" in drift.text_content() and "updating" not in drift.text_content()
    assert not drift.evaluate("(e) => e.classList.contains('stale')")
    assert page.text_content("#quality-legend-state") == f"revision {revision}"
    assert page.evaluate("window.curvefm.highlighted('target')") == int(served["X-Worst-Target"])
    screenshot(page, "10-figures-refreshed")
    page.uncheck("#show-quality")
    assert page.is_hidden("#quality-legend")


def test_the_suggested_curve_is_shown_and_accepted_as_a_curve_with_its_ends(page, demo):
    def shown_suggestion() -> dict | None:
        return page.evaluate("window.curvefm.suggestion")

    def settled() -> bool:
        shown, served = shown_suggestion(), demo.client.get(f"/sessions/{DEMO_SESSION}/suggestion").json()
        return bool(shown and shown["revision"] == served["revision"] and not served["prior_pending"]) and all(
            shown[side] == served[side] for side in ("source", "target")
        )

    def line(side: str) -> dict | None:
        return page.evaluate("(side) => window.curvefm.suggestionLine(side)", side)

    def drawn_between_ends() -> bool:
        ends = shown_suggestion()
        return all((line(side) or {}).get("ends") == ends[side] for side in ("source", "target"))

    wait_until(settled, "the page shows the suggestion the service makes now")
    assert page.is_enabled("#accept-suggestion")
    wait_until(drawn_between_ends, "the suggested curve is drawn between its ends on both shapes")
    assert all(line(side)["points"] > 2 for side in ("source", "target"))  # a path, not a segment between the ends
    screenshot(page, "13-suggested-curve")
    # move an end the camera shows: click it, then click where it belongs; the curve is traced again to it
    side, index = pick_suggested_end(page, shown_suggestion())
    elsewhere = next(v for v in pickable_vertices(page) if v["id"] not in shown_suggestion()[side])
    page.mouse.click(*elsewhere[side])
    suggested = shown_suggestion()
    assert suggested[side][index] == elsewhere["id"]
    wait_until(lambda: (line(side) or {}).get("ends", [None, None])[index] == elsewhere["id"], "the line follows")
    assert drawn_between_ends() and line(side)["points"] > 1
    before = session(demo)
    samples = page.evaluate("window.curvefmStats.samples.length")
    page.keyboard.press("a")
    page.wait_for_function("(n) => window.curvefmStats.samples.length > n", arg=samples, timeout=30_000)
    after = session(demo)
    assert len(after["curves"]) == len(before["curves"]) + 1
    added = after["curves"][-1]
    ends = {side: [added[f"path_{side}"][0], added[f"path_{side}"][-1]] for side in ("source", "target")}
    assert ends == {side: suggested[side] for side in ("source", "target")}
    # the next suggestion belongs to the new revision; unchecking the box hides it and disables the button
    wait_until(lambda: (shown_suggestion() or {}).get("revision") == after["revision"], "a new suggestion is shown")
    page.uncheck("#show-suggestion")
    assert not page.is_enabled("#accept-suggestion")


NEAR_PIXEL_JS = """
([side, vertex, within]) => {
  const end = window.curvefm.vertexToScreen(side, vertex);
  if (!end.visible) return null;
  for (let r = 0; r <= within; r++) {
    for (let dx = -r; dx <= r; dx++) {
      for (let dy = -r; dy <= r; dy++) {
        if (Math.max(Math.abs(dx), Math.abs(dy)) !== r) continue;
        const x = Math.round(end.x) + dx, y = Math.round(end.y) + dy;
        const id = window.curvefm.screenToVertex(side, x, y);
        if (id === null) continue;
        const at = window.curvefm.vertexToScreen(side, id);
        if (Math.hypot(at.x - end.x, at.y - end.y) <= within) return [x, y];
      }
    }
  }
  return null;
}
"""


def pick_suggested_end(page, suggestion: dict, within: int = 8) -> tuple[str, int]:
    """Click near a suggested end until the page takes it for moving (an end behind the shape is not clickable:
    the click lands on the front, and Escape cancels it), turning the linked cameras when none is in view; return
    its side and index."""
    for _ in range(4):
        for side in ("source", "target"):
            for index, vertex in enumerate(suggestion[side]):
                pixel = page.evaluate(NEAR_PIXEL_JS, [side, vertex, within])
                if pixel is None:
                    continue
                page.mouse.click(*pixel)
                if "suggested curve belongs" in page.inner_text("#hint"):
                    return side, index
                page.keyboard.press("Escape")
        turn_cameras(page)
    raise AssertionError(f"no end of the suggested curve {suggestion} could be clicked from four sides")


def turn_cameras(page) -> None:
    """Drag across the source view: the linked cameras turn both shapes (a drag is no click)."""
    box = page.locator("#source-view canvas").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x - box["width"] / 4, y)
    page.mouse.down()
    page.mouse.move(x + box["width"] / 4, y, steps=8)
    page.mouse.up()
    next_frames(page)


def test_a_read_only_session_refuses_clicks_before_they_are_made(browser, demo):
    """A session shared for reading says so before the first click; clicks add no point and send nothing."""
    record = session(demo)
    body = {"source": record["source"], "target": record["target"], "k": record["k"], "sharing": "read"}
    shared = demo.client.post("/sessions", json=body).raise_for_status().json()["id"]
    demo.client.post(f"/sessions/{shared}/curves", json={"source": [19, 432], "target": [19, 432]}).raise_for_status()
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    sent = []
    page.on("request", lambda r: r.method != "GET" and "/sessions/" in r.url and sent.append(r.url))
    open_session(page, demo.url, shared, token=add_user(demo.data_dir, "reader"))
    try:
        assert "Read-only" in page.text_content("#hint") and "read-only" in page.text_content("#session-title")
        ((a, b),) = endpoint_pairs(pickable_vertices(page), 1, seed=2)
        for point in (a, b):
            for side in ("source", "target"):
                page.mouse.click(*point[side])
        page.wait_for_selector(".toast:has-text('Read-only')")
        next_frames(page)
        assert page.locator(".toast:has-text('Read-only')").count() == 1  # said once, not at every click
        assert sent == [] and len(session_of(demo, shared)["curves"]) == 1
        assert page.evaluate("window.curvefm.tubeCount('source')") == 1  # no marker, no new curve
        assert page.is_disabled("#curve-list button[data-action='delete']")
        assert page.is_disabled("#curve-list button[data-action='retrace']") and page.is_disabled("#undo-button")
        assert page.is_disabled("#cancel-pending")  # no click was kept
        screenshot(page, "11-read-only")
    finally:
        context.close()


def session_of(demo, session_id: str) -> dict:
    return demo.client.get(f"/sessions/{session_id}").raise_for_status().json()


def listed_curves(page) -> list[str]:
    return page.eval_on_selector_all("#curve-list li", "(items) => items.map((item) => item.dataset.curveId)")


def test_undo_after_delete_brings_the_curve_back_with_its_id_colour_and_place(page, demo):
    ids = listed_curves(page)
    middle = ids[len(ids) // 2]
    item = f'#curve-list li[data-curve-id="{middle}"]'
    colour = page.eval_on_selector(f"{item} .swatch", "(swatch) => swatch.style.background")
    page.click(f'{item} button[data-action="delete"]')
    page.wait_for_selector(item, state="detached")
    assert f"{len(ids) - 1} curves" in page.text_content("#session-select option:checked")  # the list follows
    page.click("#undo-button")
    page.wait_for_selector(item)
    assert listed_curves(page) == ids == [curve["id"] for curve in session(demo)["curves"]]
    assert page.eval_on_selector(f"{item} .swatch", "(swatch) => swatch.style.background") == colour
    assert f"{len(ids)} curves" in page.text_content("#session-select option:checked")
    assert "vertices on the source" in page.get_attribute(f"{item} .curve-label", "title")

    page.click(f'{item} button[data-action="delete"]')  # the history outlives a reload of the page
    page.wait_for_selector(item, state="detached")
    page.reload()
    page.wait_for_function("() => window.curvefm && window.curvefm.ready", timeout=60_000)
    page.click("#undo-button")
    page.wait_for_selector(item)
    assert listed_curves(page) == ids == [curve["id"] for curve in session(demo)["curves"]]


def test_refinement_results_come_back_after_a_reload_and_turn_stale_after_an_edit(page, demo):
    revision = session(demo)["revision"]
    page.select_option("#converter-select", "nearest-neighbor")
    page.click("#refine-button")
    # this job's row: an earlier test's refinement, restored when the page loaded, has an ok row too
    page.wait_for_selector(
        f"#refine-progress .progress-row.ok:has-text('nearest-neighbor (revision {revision})')", timeout=60_000
    )
    page.reload()
    page.wait_for_function("() => window.curvefm && window.curvefm.ready", timeout=60_000)
    page.wait_for_selector('#downloads a[download="map_target_to_source.txt"]')
    page.wait_for_selector('input[name="map"][value="pointwise"]:not([disabled])')
    assert f"revision {revision})" in page.text_content("#pointwise-label")
    assert "stale" not in page.text_content("#refine-note")
    ((a, b),) = endpoint_pairs(pickable_vertices(page), 1, seed=4)
    click_curve(page, [a, b])
    page.wait_for_selector("#refine-note.stale")
    assert f"now revision {session(demo)['revision']}" in page.text_content("#pointwise-label")
    screenshot(page, "07-stale-refinement-after-reload")


def test_the_page_is_usable_760_pixels_wide(page, demo):
    page.set_viewport_size({"width": 760, "height": 860})
    next_frames(page)
    assert page.evaluate("document.documentElement.scrollWidth") <= 760
    for side in ("source", "target"):
        box = page.locator(f"#{side}-view canvas").bounding_box()
        assert box["width"] > 300 and box["height"] > 200 and box["x"] + box["width"] <= 760, (side, box)
    hint = page.locator("#hint").bounding_box()
    assert hint["x"] >= 0 and hint["x"] + hint["width"] <= 760, hint
    assert_hint_beside_the_views(page)
    ((a, b),) = endpoint_pairs(pickable_vertices(page), 1, seed=5, min_distance=40)
    page.mouse.click(*a["source"])  # a longer hint (two lines here) moves nothing
    views = [page.locator(f"#{side}-view canvas").bounding_box() for side in ("source", "target")]
    page.mouse.click(*b["source"])
    assert [page.locator(f"#{side}-view canvas").bounding_box() for side in ("source", "target")] == views
    assert_hint_beside_the_views(page)
    page.keyboard.press("Escape")
    click_curve(page, [a, b])
    assert_status_line_whole(page, 760)
    page.select_option("#converter-select", "rhm")
    labels = page.text_content("#converter-params")
    assert "init_zoomout" not in labels and "Init zoomout" in labels
    assert page.is_hidden("#converter-params details.advanced label")  # folded: Refine stays near
    refine, select = (page.locator(selector).bounding_box() for selector in ("#refine-button", "#converter-select"))
    assert refine["y"] - select["y"] < 120, (refine, select)
    page.check('input[name="function"][value="indicator"]')
    page.fill("#region-radius", "12")
    assert page.text_content("#region-radius-value") == "12% of the size"
    screenshot(page, "08-narrow-760px")


def test_errors_are_shown_and_the_page_stays_usable(page, demo):
    page.click("#pair-panel summary")  # upload lives in the shapes panel, folded while a session is open
    page.set_input_files("#upload-input", files=[{"name": "notes.txt", "mimeType": "text/plain", "buffer": b"hi"}])
    page.wait_for_selector(".toast.error:has-text('unsupported mesh format')")
    page.set_input_files("#upload-input", files=[{"name": "broken.off", "mimeType": "text/plain", "buffer": b"OFF\n3"}])
    page.wait_for_selector("#pair-progress .progress-row.failed:has-text('broken.off')")

    page.route("**/jobs/*", lambda route: route.fulfill(json=failed_job()))
    page.click("#refine-button")
    page.wait_for_selector("#refine-progress .progress-row.failed:has-text('worker exploded')")
    page.unroute("**/jobs/*")
    page.route("**/jobs/*", lambda route: route.fulfill(json=lost_job()))
    page.click("#refine-button")
    page.wait_for_selector("#refine-progress .progress-row.failed:has-text('the service restarted')")
    page.unroute("**/jobs/*")
    assert page.is_enabled("#refine-button")

    for pattern in ("**/sessions/**", "**/health"):
        page.route(pattern, lambda route: route.abort("connectionrefused"))
    (a, b), (c, d) = endpoint_pairs(pickable_vertices(page), 2, seed=1)
    curves_before = len(session(demo)["curves"])
    views_before = [page.locator(f"#{side}-view canvas").bounding_box() for side in ("source", "target")]
    for point in (a, b):
        for side in ("source", "target"):
            page.mouse.click(*point[side])
    page.wait_for_selector(".toast.error:has-text('The curve was not added')")  # a toast goes after 12 s: first
    page.wait_for_selector("#banner:has-text('cannot be reached')")
    assert [page.locator(f"#{side}-view canvas").bounding_box() for side in ("source", "target")] == views_before
    screenshot(page, "04-connection-lost")
    page.unroute_all()
    page.wait_for_selector("#banner", state="hidden", timeout=15_000)

    click_curve(page, [c, d])
    assert len(session(demo)["curves"]) == curves_before + 1
    screenshot(page, "05-usable-after-errors")


@pytest.mark.parametrize("width", [1366, 1400])
def test_the_status_line_is_whole_on_laptop_screens(page, demo, width):
    page.set_viewport_size({"width": width, "height": 768})
    next_frames(page)
    ((a, b),) = endpoint_pairs(pickable_vertices(page), 1, seed=6)
    views = [page.locator(f"#{side}-view canvas").bounding_box() for side in ("source", "target")]
    click_curve(page, [a, b])  # the longest status line: timings and the drift
    settled_quality(page, session(demo)["revision"])
    assert_status_line_whole(page, width)
    assert [page.locator(f"#{side}-view canvas").bounding_box() for side in ("source", "target")] == views
    assert_hint_beside_the_views(page)
    screenshot(page, f"12-status-line-{width}px")


def assert_status_line_whole(page, width: int) -> None:
    """Every part of the status line shows: nothing cut, nothing beyond the window."""
    line = page.locator("#status-line")
    text = line.text_content()
    assert "click→texture" in text and "round-trip drift" in text and "curves" in text, text
    fits = "(e) => e.scrollWidth <= e.clientWidth && e.scrollHeight <= e.clientHeight"
    box = line.bounding_box()
    assert line.evaluate(fits) and box["x"] >= 0 and box["x"] + box["width"] <= width, (box, text)


def assert_hint_beside_the_views(page) -> None:
    """The hint covers neither shape."""
    hint = page.locator("#hint").bounding_box()
    for side in ("source", "target"):
        view = page.locator(f"#{side}-view canvas").bounding_box()
        apart = (
            hint["y"] >= view["y"] + view["height"]
            or hint["y"] + hint["height"] <= view["y"]
            or hint["x"] >= view["x"] + view["width"]
            or hint["x"] + hint["width"] <= view["x"]
        )
        assert apart, (side, hint, view)


def failed_job() -> dict:
    return {
        "id": "mocked",
        "kind": "refine",
        "state": "failed",
        "progress": 0.3,
        "message": "failed",
        "error": {"kind": "internal", "message": "worker exploded"},
        "links": {},
    }


def lost_job() -> dict:
    reason = "the service restarted while the job was running; retry it (POST /jobs/mocked/retry)"
    return {**failed_job(), "state": "lost", "message": reason, "error": {"kind": "lost", "message": reason}}


def test_mount_ui_names_a_missing_three_js(tmp_path, monkeypatch):
    monkeypatch.setenv("CURVEFM_THREE_DIR", str(tmp_path / "nowhere"))
    app = FastAPI()
    mount_ui(app)

    async def get(*paths: str) -> list[httpx.Response]:
        async with httpx.AsyncClient(transport=httpx.ASGITransport(app=app), base_url="http://ui") as client:
            return [await client.get(path) for path in paths]

    # a thread of its own: Playwright's sync API may hold this thread's event loop
    with ThreadPoolExecutor(1) as pool:
        fetched = pool.submit(asyncio.run, get("/vendor/three/build/three.module.js", "/", "/app.js"))
        three, page, script = fetched.result()
    assert three.status_code == 404 and "npm install" in three.json()["detail"]
    assert page.text.startswith("<!doctype html>") and script.status_code == 200
