"""Makes the documentation's screenshots of the web UI from the demo, as a new user sees it: a fresh data
directory, ``curvefm serve --demo``, the login URL it prints, Chromium at 1400 x 860. ``docs/images/ui.png`` is
the demo session as it opens; ``docs/images/ui-refined.png`` the same after a ZoomOut refinement from the page.

Run from the checkout after ``scripts/setup.sh test``: ``.venv/bin/python scripts/screenshots.py``.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from playwright.sync_api import sync_playwright

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests"))
from support.ui import VIEWPORT, launch, next_frames, refine_in_page  # noqa: E402

IMAGES = REPO / "docs" / "images"
PORT = 18731
SETTLED = "() => { const drift = document.querySelector('#status-drift'); return drift && !drift.matches('.stale'); }"


def serve_demo(data: Path, log: Path) -> tuple[subprocess.Popen, str]:
    """The demo service on ``data``, and the login URL it printed."""
    command = [sys.executable, "-m", "curvefm.service", "--demo", "--port", str(PORT), "--data", str(data)]
    server = subprocess.Popen(command, stdout=log.open("wb"), stderr=subprocess.STDOUT)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        found = re.search(rf"http://127\.0\.0\.1:{PORT}/\?token=\S+", log.read_text())
        if found:
            return server, found.group(0)
        time.sleep(0.2)
    server.kill()
    raise SystemExit(f"the demo did not print its login URL:\n{log.read_text()[-2000:]}")


def main() -> None:
    with tempfile.TemporaryDirectory() as folder:
        server, login = serve_demo(Path(folder) / "data", Path(folder) / "serve.log")
        try:
            with sync_playwright() as playwright:
                page = launch(playwright).new_page(viewport=VIEWPORT)
                page.goto(login)
                page.wait_for_function("() => window.curvefm && window.curvefm.ready", timeout=120_000)
                # the figures settle once the landmark prior has landed
                page.wait_for_function(SETTLED, timeout=60_000)
                next_frames(page)
                page.screenshot(path=str(IMAGES / "ui.png"))
                refine_in_page(page, "zoomout")
                page.screenshot(path=str(IMAGES / "ui-refined.png"))
        finally:
            server.terminate()
            server.wait(timeout=30)
    print(f"screenshots written to {IMAGES.relative_to(REPO)}")


if __name__ == "__main__":
    main()
