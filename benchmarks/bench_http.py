"""Curve edits over HTTP on a 30k-vertex pair (TOSCA cat0 -> cat1, 27894 vertices, k = 120).

Starts ``python -m curvefm.service`` (embedded jobs) on a free port, uploads both shapes, computes their bases
through the job queue (reused from ``--data`` when given), then measures:

* ``single``: round trip of ``POST /sessions/{id}/curves`` (trace on both shapes, solve the source -> target
  map, write the session durably, answer) for ``--curves`` curves added one after another to one session;
* ``concurrent``: ``--sessions`` sessions on the same pair, one client thread each, every thread adding
  ``--per-session`` curves as fast as it can: throughput and per-request latency. Client threads share the
  machine's cores with the server.

Endpoints are seeded random vertex pairs (the same ids on both shapes: TOSCA's cat poses correspond by id),
mostly far apart: long curves, the slow case for tracing. Prints JSON.

Usage: ``python -m benchmarks.bench_http [--data DIR] [--curves N] [--sessions S] [--per-session M]``
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import threading
import time
from datetime import date
from pathlib import Path

import httpx
import numpy as np

from benchmarks.common import shared_data, start_server

SHARED = shared_data()
SHAPES = ("cat0.off", "cat1.off")


def prepare_pair(client: httpx.Client, k: int) -> tuple[list[str], int]:
    ids, n_vertices = [], 0
    for name in SHAPES:
        with open(SHARED / "tosca" / name, "rb") as f:
            shape = client.post("/shapes", files={"file": (name, f)}).raise_for_status().json()
        ids.append(shape["id"])
        n_vertices = shape["n_vertices"]
    for shape_id in ids:
        job = client.post(f"/shapes/{shape_id}/bases", json={"k": k}).raise_for_status().json()
        while (info := client.get(f"/jobs/{job['id']}").json())["state"] not in ("finished", "failed"):
            time.sleep(0.5)
        if info["state"] != "finished":
            raise SystemExit(f"basis job failed: {info['error']}")
    return ids, n_vertices


def add_curves(client: httpx.Client, session_id: str, pairs: np.ndarray) -> tuple[list[float], list[float]]:
    """Round-trip times (ms) of adding one curve per endpoint pair and reading the texture it carries (as the
    UI does: the map is solved on that read), and the server's solve times (ms) within them."""
    round_trips, solves = [], []
    for a, b in pairs.tolist():
        started = time.perf_counter()
        client.post(f"/sessions/{session_id}/curves", json={"source": [a, b], "target": [a, b]}).raise_for_status()
        texture = client.get(f"/sessions/{session_id}/transfer", params={"function": "uv"}).raise_for_status()
        round_trips.append(1e3 * (time.perf_counter() - started))
        solves.append(float(texture.headers["X-Solve-Ms"]))
    return round_trips, solves


def percentiles(ms: list[float]) -> dict:
    return {
        "p50_ms": round(float(np.percentile(ms, 50)), 1),
        "p95_ms": round(float(np.percentile(ms, 95)), 1),
    }


def new_session(client: httpx.Client, ids: list[str], k: int) -> str:
    body = {"source": ids[0], "target": ids[1], "k": k}
    return client.post("/sessions", json=body).raise_for_status().json()["id"]


def bench_single(client, ids, k, n_vertices, count, rng) -> dict:
    session_id = new_session(client, ids, k)
    add_curves(client, session_id, rng.integers(0, n_vertices, (1, 2)))  # builds the live session: not timed
    round_trips, solves = add_curves(client, session_id, rng.integers(0, n_vertices, (count, 2)))
    return {"curves": count, **percentiles(round_trips), "server_solve_p50_ms": percentiles(solves)["p50_ms"]}


def bench_concurrent(url, headers, ids, k, n_vertices, sessions, per_session, rng) -> dict:
    clients = [httpx.Client(base_url=url, timeout=120, headers=headers) for _ in range(sessions)]
    session_ids = [new_session(client, ids, k) for client in clients]
    for client, session_id in zip(clients, session_ids, strict=True):
        add_curves(client, session_id, rng.integers(0, n_vertices, (1, 2)))
    work = [rng.integers(0, n_vertices, (per_session, 2)) for _ in range(sessions)]
    latencies: list[float] = []
    lock = threading.Lock()

    def run(index: int) -> None:
        round_trips, _ = add_curves(clients[index], session_ids[index], work[index])
        with lock:
            latencies.extend(round_trips)

    threads = [threading.Thread(target=run, args=(i,)) for i in range(sessions)]
    started = time.perf_counter()
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    elapsed = time.perf_counter() - started
    for client in clients:
        client.close()
    return {
        "sessions": sessions,
        "requests": len(latencies),
        "throughput_per_s": round(len(latencies) / elapsed, 1),
        **percentiles(latencies),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, help="data directory (kept; reuses bases); default: a temporary one")
    parser.add_argument("--k", type=int, default=120)
    parser.add_argument("--curves", type=int, default=50)
    parser.add_argument("--sessions", type=int, default=20)
    parser.add_argument("--per-session", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="curvefm-bench-") as scratch:
        server, url, headers = start_server(args.data or Path(scratch))
        try:
            with httpx.Client(base_url=url, timeout=600, headers=headers) as client:
                started = time.perf_counter()
                ids, n_vertices = prepare_pair(client, args.k)
                prepare_s = time.perf_counter() - started
                rng = np.random.default_rng(args.seed)
                single = bench_single(client, ids, args.k, n_vertices, args.curves, rng)
            concurrent = bench_concurrent(url, headers, ids, args.k, n_vertices, args.sessions, args.per_session, rng)
        finally:
            server.kill()
            server.wait()
    report = {
        "benchmark": "curve add over HTTP",
        "shapes": [f"tosca/{name}" for name in SHAPES],
        "vertices": n_vertices,
        "k": args.k,
        "upload_and_bases_s": round(prepare_s, 1),
        "single": single,
        "concurrent": concurrent,
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}",
        "date": date.today().isoformat(),
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
