"""The demo (``curvefm serve --demo``): generated shapes, bases with logged progress, a ready session."""

from __future__ import annotations

import time

import numpy as np

from curvefm.service.demo import DEMO_SESSION, demo_curves, demo_shapes


def wait_for_demo(api, timeout: float = 180) -> dict:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        response = api.client.get(f"/sessions/{DEMO_SESSION}")
        if response.status_code == 200 and len(response.json()["curves"]) == len(demo_curves(demo_shapes()[0])):
            return response.json()
        time.sleep(0.5)
    raise AssertionError(f"the demo session was not ready after {timeout} s:\n{api.log.read_text()[-3000:]}")


def test_demo_prepares_shapes_bases_and_a_session(processes, tmp_path):
    api = processes.api(tmp_path / "data", args=("--demo",))
    session = wait_for_demo(api)
    # the test's user is not an admin, and with a user the server makes no local admin: the demo belongs to nobody
    assert (session["owner"], session["sharing"]) == ("", "edit")
    log = api.log.read_text()
    assert "demo: basis of demo-animal" in log and "%" in log  # progress was shown
    for shape in (session["source"], session["target"]):
        mesh = api.client.get(f"/shapes/{shape}/mesh", params={"format": "json"}).json()
        assert len(mesh["vertices"]) == 4098
    transfer = api.client.get(f"/sessions/{DEMO_SESSION}/transfer", params={"function": "xyz"})
    xyz = np.frombuffer(transfer.raise_for_status().content, "<f4").reshape(-1, 3)
    assert np.isfinite(xyz).all() and xyz.std(axis=0).min() > 0.05  # the map carries real structure

    processes.kill(api.process)
    restarted = processes.api(tmp_path / "data", args=("--demo",))
    assert restarted.client.get(f"/sessions/{DEMO_SESSION}").json()["revision"] == session["revision"]
