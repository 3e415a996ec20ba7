"""Two API processes on one data directory (what an operator runs under load): edits of a session are
serialised across the processes, a process whose live solver is behind brings it up to date, curve ids stay
unique and no acknowledged edit is lost."""

from __future__ import annotations

import subprocess
import sys
import threading
import time

import httpx
import numpy as np
import pytest

K = 30
THREADS, ADDS = 4, 6


@pytest.fixture(scope="module")
def replicas(module_processes, tmp_path_factory):
    """Two embedded-mode API processes on one data directory, with the demo shapes and their bases."""
    folder = tmp_path_factory.mktemp("replicas")
    first = module_processes.api(folder / "data")
    first.shapes, _ = first.demo_pair(folder, K)
    second = module_processes.api(folder / "data")
    return first, second


def new_session(replicas) -> str:
    first, _ = replicas
    body = {"source": first.shapes[0], "target": first.shapes[1], "k": K}
    return first.client.post("/sessions", json=body).raise_for_status().json()["id"]


def add(api, session: str, a: int, b: int) -> dict:
    response = api.client.post(f"/sessions/{session}/curves", json={"source": [a, b], "target": [a, b]})
    assert response.status_code == 201, response.text
    return response.json()


def map_of(api, session: str) -> tuple[np.ndarray, int]:
    body = api.client.get(f"/sessions/{session}/map").raise_for_status().json()
    return np.array(body["C_source_to_target"]), body["revision"]


def test_concurrent_adds_alternating_between_two_processes_are_all_kept(replicas):
    session = new_session(replicas)
    acknowledged: list[list[dict]] = [[] for _ in range(THREADS)]
    failures: list[BaseException] = []

    def adds(worker: int) -> None:
        rng = np.random.default_rng(worker)
        clients = [httpx.Client(base_url=api.url, timeout=120, headers=api.client.headers) for api in replicas]
        try:
            for i in range(ADDS):
                a, b = (int(v) for v in rng.choice(4098, 2, replace=False))
                curve = {"source": [a, b], "target": [a, b]}
                response = clients[(worker + i) % 2].post(f"/sessions/{session}/curves", json=curve)
                assert response.status_code == 201, response.text
                acknowledged[worker].append(response.json())
        except BaseException as exc:  # noqa: BLE001  (re-raised by the test thread below)
            failures.append(exc)
        finally:
            for client in clients:
                client.close()

    threads = [threading.Thread(target=adds, args=(worker,)) for worker in range(THREADS)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not failures, failures
    edits = [edit for mine in acknowledged for edit in mine]
    records = [api.client.get(f"/sessions/{session}").raise_for_status().json() for api in replicas]
    assert records[0] == records[1]
    stored = {curve["id"]: curve for curve in records[0]["curves"]}
    assert len(stored) == len(records[0]["curves"]) == THREADS * ADDS  # ids unique, every add kept
    assert all(stored[edit["curve"]["id"]] == edit["curve"] for edit in edits)
    assert sorted(edit["map"]["revision"] for edit in edits) == list(range(1, THREADS * ADDS + 1))
    for mine in acknowledged:
        revisions = [edit["map"]["revision"] for edit in mine]
        assert revisions == sorted(set(revisions))  # each client saw its own edits in order
    assert records[0]["revision"] == THREADS * ADDS and records[0]["next_curve"] == THREADS * ADDS + 1


def test_a_process_brings_a_session_another_process_changed_up_to_date(replicas):
    first, second = replicas
    session = new_session(replicas)
    add(first, session, 0, 2000)
    one_curve, _ = map_of(first, session)  # the first process's solver now holds c1
    assert add(second, session, 100, 3000)["curve"]["id"] == "c2"
    C_first, revision_first = map_of(first, session)
    C_second, revision_second = map_of(second, session)
    assert revision_first == revision_second == 2
    np.testing.assert_allclose(C_first, C_second, atol=1e-9 * np.abs(C_second).max())
    assert not np.allclose(C_first, one_curve, atol=1e-6)
    transfer = first.client.get(f"/sessions/{session}/transfer", params={"function": "xyz"})
    assert transfer.headers["X-Revision"] == "2"

    replaced = second.client.put(f"/sessions/{session}/curves/c1", json={"source": [5, 2500], "target": [5, 2500]})
    assert replaced.status_code == 200, replaced.text
    assert first.client.delete(f"/sessions/{session}/curves/c2").status_code == 200
    assert add(first, session, 50, 1500)["curve"]["id"] == "c3"
    record = second.client.get(f"/sessions/{session}").json()
    assert [c["id"] for c in record["curves"]] == ["c1", "c3"] and record["curves"][0]["spec"]["source"] == [5, 2500]
    C_first, revision_first = map_of(first, session)
    C_second, revision_second = map_of(second, session)
    assert revision_first == revision_second == record["revision"] == 5
    np.testing.assert_allclose(C_first, C_second, atol=1e-9 * np.abs(C_second).max())


HOLD_LOCK = """
import sqlite3, sys
connection = sqlite3.connect(sys.argv[1], isolation_level=None)
connection.execute("BEGIN IMMEDIATE")  # the database's write lock, as a writer stuck in its transaction
print("held", flush=True)
sys.stdin.read()  # until the test closes our stdin
"""


@pytest.mark.sqlite_only
def test_a_database_held_by_a_stuck_process_answers_503_naming_it_then_recovers(
    replicas, module_processes, tmp_path, module_database
):
    if module_database != "sqlite":
        pytest.skip("SQLite's write lock")
    first, _ = replicas
    impatient = module_processes.api(first.data_dir, env={"CURVEFM_SQLITE_BUSY_TIMEOUT": "500"})
    session = new_session(replicas)
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD_LOCK, str(first.data_dir / "curvefm.db")],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "held"
        started = time.monotonic()
        busy = impatient.client.post(f"/sessions/{session}/curves", json={"source": [1, 900], "target": [1, 900]})
        assert busy.status_code == 503, busy.text
        assert busy.json()["error"] == "unavailable" and "records' database" in busy.json()["detail"]
        assert busy.headers["Retry-After"] and time.monotonic() - started < 10
        assert impatient.client.get("/health").status_code == 200
        assert impatient.client.get(f"/sessions/{session}").json()["curves"] == []  # nothing half-written
    finally:
        holder.stdin.close()
        holder.wait(timeout=30)
    edit = add(impatient, session, 1, 900)
    assert edit["map"]["n_curves"] == 1
