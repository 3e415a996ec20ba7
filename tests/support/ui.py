"""Driving the web UI in Chromium (Playwright), shared by the browser tests (tests/ui/ and a few others) and
benchmarks/bench_ui_latency.py.

Clicks are real mouse clicks at the pixels where the page draws a vertex; the page's test hooks
(``window.curvefm.vertexToScreen`` / ``screenToVertex``, file ids) say where that is.
"""

from __future__ import annotations

import io
import os
import random
from pathlib import Path

import numpy as np

from support.paths import ARTIFACTS

CHROMIUM = Path(os.environ.get("CURVEFM_CHROMIUM", "/usr/bin/chromium"))
VIEWPORT = {"width": 1400, "height": 860}
MIN_CHANGED = 0.003  # share of the target canvas's pixels a new curve must visibly recolour

# Vertices a click picks on both viewports (same file id on both shapes: pairs whose vertices correspond by
# id), sampled on a grid over the source canvas, with the integer pixel positions that pick them.
_PICKABLE_JS = """
(grid) => {
  const snapped = (side, id) => {
    const p = window.curvefm.vertexToScreen(side, id);
    if (!p.visible) return null;
    const x = Math.round(p.x), y = Math.round(p.y);
    return window.curvefm.screenToVertex(side, x, y) === id ? [x, y] : null;
  };
  const box = document.querySelector("#source-view canvas").getBoundingClientRect();
  const found = new Map();
  for (let i = 0; i < grid; i++) {
    for (let j = 0; j < grid; j++) {
      const x = box.left + ((i + 0.5) / grid) * box.width, y = box.top + ((j + 0.5) / grid) * box.height;
      const id = window.curvefm.screenToVertex("source", x, y);
      if (id === null || found.has(id)) continue;
      const source = snapped("source", id), target = snapped("target", id);
      if (source && target) found.set(id, { id, source, target });
    }
  }
  return [...found.values()];
}
"""


def launch(playwright):
    """Headless Debian Chromium; WebGL comes from SwiftShader with Playwright's default flags."""
    return playwright.chromium.launch(executable_path=str(CHROMIUM), headless=True, args=["--no-sandbox"])


def open_session(page, url: str, session_id: str, token: str | None = None, timeout_ms: float = 60_000) -> None:
    """Load the UI on a session (logging in with ``token`` as the login URL does, unless the page's browser
    context has the login cookie already) and wait until its first texture is drawn; otherwise fail with what the
    page says (its banners and loading message name the cause, e.g. three.js not installed, or no login)."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    page.goto(f"{url}/?session={session_id}" + (f"&token={token}" if token else ""))
    try:
        # predicates are functions: a bare expression is eval()ed in the page, which its CSP forbids
        page.wait_for_function("() => window.curvefm && window.curvefm.ready", timeout=timeout_ms)
    except PlaywrightTimeout:
        shown = "#banner, #login-needed, #loading, .toast"
        said = page.evaluate(f"[...document.querySelectorAll('{shown}')].map((e) => e.hidden ? '' : e.innerText)")
        raise AssertionError(f"the UI did not show session {session_id}: {said}") from None


def pickable_vertices(page, grid: int = 24) -> list[dict]:
    """[{id, source: [x, y], target: [x, y]}]: vertices clickable at those pixels on both shapes."""
    return page.evaluate(_PICKABLE_JS, grid)


def endpoint_pairs(candidates: list[dict], count: int, seed: int = 0, min_distance: float = 80) -> list[tuple]:
    """``count`` different pairs of candidates at least ``min_distance`` pixels apart on both shapes."""

    def apart(a: dict, b: dict) -> bool:
        return all(np.hypot(*np.subtract(a[side], b[side])) >= min_distance for side in ("source", "target"))

    pairs = [(a, b) for i, a in enumerate(candidates) for b in candidates[i + 1 :] if apart(a, b)]
    if len(pairs) < count:
        raise AssertionError(f"only {len(pairs)} of {count} well separated vertex pairs are clickable")
    return random.Random(seed).sample(pairs, count)


def sample_count(page) -> int:
    return page.evaluate("window.curvefmStats.samples.length")


def click_curve(page, points: list[dict], timeout_ms: float = 30_000) -> dict:
    """Click a curve through ``points`` (start, Shift+clicked waypoints, end) on the source, then on the
    target; wait until the new texture is drawn and return the page's timing sample of that edit. Clicks are
    paced as a person's would be: each waits until the marker of the one before is on screen."""
    before = sample_count(page)
    clicks = [(side, index, point) for side in ("source", "target") for index, point in enumerate(points)]
    for number, (side, index, point) in enumerate(clicks):
        waypoint = 0 < index < len(points) - 1
        if waypoint:
            page.keyboard.down("Shift")
        page.mouse.click(*point[side])
        if waypoint:
            page.keyboard.up("Shift")
        if number < len(clicks) - 1:
            next_frames(page)
    page.wait_for_function("(before) => window.curvefmStats.samples.length > before", arg=before, timeout=timeout_ms)
    return page.evaluate("window.curvefmStats.last")


def refine_in_page(page, converter: str = "nearest-neighbor") -> None:
    """Refine the open session from the page and wait until the target shows the refinement's pointwise map."""
    page.select_option("#converter-select", converter)
    page.click("#refine-button")
    page.wait_for_selector("#refine-progress .progress-row.ok", timeout=60_000)
    page.wait_for_function('() => document.querySelector(\'input[name="map"][value="pointwise"]\').checked')
    next_frames(page)


def next_frames(page) -> None:
    """Wait for two animation frames: whatever the page changed before is on screen."""
    page.evaluate("new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done)))")


def canvas_pixels(page, side: str) -> np.ndarray:
    """The drawn pixels of one viewport's canvas (RGB, uint8)."""
    from PIL import Image

    png = page.locator(f"#{side}-view canvas").screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def changed_fraction(before: np.ndarray, after: np.ndarray, threshold: int = 12) -> float:
    """Share of pixels whose colour moved by more than ``threshold`` in some channel."""
    return float((np.abs(before.astype(int) - after.astype(int)).max(axis=2) > threshold).mean())


CSP_WATCH = (
    "document.addEventListener('securitypolicyviolation', (e) => "
    "(window.cspViolations = window.cspViolations || []).push(e.violatedDirective + ' ' + e.blockedURI))"
)


class PageWatch:
    """What a browser context asked for beyond ``origin`` (those requests are aborted, as on a network without
    internet) and the Content-Security-Policy violations of its pages."""

    def __init__(self, context, origin: str):
        self.origin, self.elsewhere = origin, []
        context.add_init_script(CSP_WATCH)
        context.route("**/*", self._route)

    def _route(self, route) -> None:
        url = route.request.url
        if url.startswith(self.origin + "/") or url.startswith(("data:", "blob:")):
            route.continue_()
        else:
            self.elsewhere.append(url)
            route.abort()

    @staticmethod
    def violations(page) -> list[str]:
        return page.evaluate("window.cspViolations || []")


def screenshot(page, name: str) -> None:
    """Save the page as ``test-artifacts/ui/<name>.png``."""
    folder = ARTIFACTS / "ui"
    folder.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(folder / f"{name}.png"))
