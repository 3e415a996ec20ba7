"""Kill -9 of the API while curves are being added: after a restart every acknowledged curve is there."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import httpx
import numpy as np
from support.processes import bearer

K = 30
ACKNOWLEDGED_BEFORE_KILL = 12


def add_curves_until_refused(api, session_id: str, acknowledged: list[dict], enough: threading.Event) -> None:
    rng = np.random.default_rng(0)
    with httpx.Client(base_url=api.url, timeout=30, headers=bearer(api.token)) as client:
        while True:
            a, b = (int(v) for v in rng.choice(4000, 2, replace=False))
            try:
                response = client.post(f"/sessions/{session_id}/curves", json={"source": [a, b], "target": [a, b]})
            except httpx.TransportError:
                return  # the server is gone
            acknowledged.append(response.raise_for_status().json()["curve"])
            if len(acknowledged) >= ACKNOWLEDGED_BEFORE_KILL:
                enough.set()


def test_acknowledged_curves_survive_kill_9(processes, tmp_path):
    data = tmp_path / "data"
    api = processes.api(data)
    _, session_id = api.demo_pair(tmp_path, K, suffix=".ply")
    acknowledged: list[dict] = []
    enough = threading.Event()
    with ThreadPoolExecutor(max_workers=1) as pool:
        adder = pool.submit(add_curves_until_refused, api, session_id, acknowledged, enough)
        while not enough.wait(timeout=0.1):
            if adder.done():
                adder.result()  # raises what stopped the adder
        processes.kill(api.process)  # SIGKILL while the adder keeps sending
        adder.result(timeout=60)

    restarted = processes.api(data)
    stored = {c["id"]: c for c in restarted.client.get(f"/sessions/{session_id}").raise_for_status().json()["curves"]}
    for curve in acknowledged:
        assert stored[curve["id"]] == curve
    assert len(stored) in (len(acknowledged), len(acknowledged) + 1)  # plus at most the one in flight

    edit = restarted.client.post(f"/sessions/{session_id}/curves", json={"source": [0, 100], "target": [0, 100]})
    edit = edit.raise_for_status().json()
    assert edit["curve"]["id"] not in stored
    assert edit["map"]["n_curves"] == len(stored) + 1
    transfer = restarted.client.get(f"/sessions/{session_id}/transfer", params={"function": "xyz"})
    assert transfer.raise_for_status().headers["X-Shape"] == "4098,3"
