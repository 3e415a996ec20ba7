"""A big shape in the web UI, drawn as a display copy: Debian's Chromium (headless, SwiftShader) against a real
server whose threshold is set low (``CURVEFM_DISPLAY_VERTICES=3000``) so that FAUST's 6,890-vertex scans are
drawn coarse. Curves are clicked with the mouse on the coarse surface; screenshots go to ``test-artifacts/ui/``."""

from __future__ import annotations

import re

import numpy as np
import pytest
from support.display import decode, display_server, mesh
from support.ui import (
    MIN_CHANGED,
    VIEWPORT,
    canvas_pixels,
    changed_fraction,
    click_curve,
    next_frames,
    open_session,
    refine_in_page,
    screenshot,
)

# Per side, vertices a click picks (file ids) with the integer pixel that picks them, sampled on a grid.
DRAWN_JS = """
(grid) => {
  const found = {};
  for (const side of ["source", "target"]) {
    const box = document.querySelector(`#${side}-view canvas`).getBoundingClientRect();
    const ids = new Map();
    for (let i = 0; i < grid * grid; i++) {
      const x = box.left + ((Math.floor(i / grid) + 0.5) / grid) * box.width;
      const id = window.curvefm.screenToVertex(side, x, box.top + ((i % grid) + 0.5) / grid * box.height);
      if (id === null || ids.has(id)) continue;
      const at = window.curvefm.vertexToScreen(side, id);
      const pixel = [Math.round(at.x), Math.round(at.y)];
      if (at.visible && window.curvefm.screenToVertex(side, ...pixel) === id) ids.set(id, pixel);
    }
    found[side] = [...ids];
  }
  return found;
}
"""


@pytest.fixture(scope="module")
def server(module_processes, tmp_path_factory, shared_data):
    return display_server(module_processes, tmp_path_factory.mktemp("ui-display"), shared_data)


@pytest.fixture
def page(browser, server):
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    errors = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    open_session(page, server.url, server.session, token=server.token)
    yield page
    context.close()
    assert not errors, f"uncaught errors in the page: {errors}"


def far_apart(candidates: list) -> tuple:
    """The two candidates (file id, pixel) furthest apart on screen."""
    pixels = np.array([pixel for _, pixel in candidates], dtype=float)
    distance = np.linalg.norm(pixels[:, None] - pixels[None], axis=2)
    i, j = np.unravel_index(np.argmax(distance), distance.shape)
    return candidates[i], candidates[j]


def tubes(page) -> list[int]:
    return [page.evaluate(f"window.curvefm.tubeCount('{side}')") for side in ("source", "target")]


def test_a_click_on_the_display_copy_picks_real_vertices_and_curves_stay_visible(page, server):
    status = page.text_content("#status-line")
    assert re.search(r"display copy: source [0-9,]+ of 6,890, target [0-9,]+ of 6,890 vertices", status), status
    assert tubes(page) == [2, 2]  # the curves added over the API, their paths placed by POST .../points
    drawn = [set(mesh(server, shape)[1]["vertex_ids"].tolist()) for shape in server.shapes]

    candidates = page.evaluate(DRAWN_JS, 24)
    (start_s, at_start_s), (end_s, at_end_s) = far_apart(candidates["source"])
    (start_t, at_start_t), (end_t, at_end_t) = far_apart(candidates["target"])
    before = canvas_pixels(page, "target")
    sample = click_curve(page, [{"source": at_start_s, "target": at_start_t}, {"source": at_end_s, "target": at_end_t}])
    assert sample["kind"] == "add" and changed_fraction(before, canvas_pixels(page, "target")) > MIN_CHANGED

    record = server.client.get(f"/sessions/{server.session}").raise_for_status().json()
    new = record["curves"][-1]
    assert new["spec"]["source"] == [start_s, end_s] and new["spec"]["target"] == [start_t, end_t]
    assert {start_s, end_s} <= drawn[0] and {start_t, end_t} <= drawn[1]  # FAUST's file ids are its internal ids
    assert new["path_source"][0] == start_s and new["path_source"][-1] == end_s
    assert not set(new["path_source"]) <= drawn[0]  # the traced path runs through vertices the copy does not draw
    assert tubes(page) == [3, 3]

    screenshot(page, "display-01-curves-on-the-display-copy")
    with_curves = canvas_pixels(page, "source")
    page.uncheck("#show-curves")
    next_frames(page)
    shown = changed_fraction(with_curves, canvas_pixels(page, "source"))
    assert shown > MIN_CHANGED, f"the curves barely show over the coarse surface ({shown:.4f})"


def test_the_weakest_vertex_is_ringed_at_its_nearest_drawn_vertex(page, server):
    served = server.client.get(f"/sessions/{server.session}/quality").raise_for_status().headers
    page.check("#show-quality")
    next_frames(page)
    for side, shape, worst in zip(
        ("source", "target"), server.shapes, (served["X-Worst-Source"], served["X-Worst-Target"]), strict=True
    ):
        placed = server.client.post(f"/shapes/{shape}/points", json={"vertices": [int(worst)]}).raise_for_status()
        row = int(decode(placed.content)[1]["nearest_row"][0])
        expected = int(mesh(server, shape)[1]["file_ids"][row])
        assert page.evaluate(f"window.curvefm.highlighted('{side}')") == expected


def test_the_pointwise_map_shows_on_display_copies(page, server):
    before = canvas_pixels(page, "target")
    refine_in_page(page)
    screenshot(page, "display-02-pointwise")
    assert changed_fraction(before, canvas_pixels(page, "target")) > MIN_CHANGED
