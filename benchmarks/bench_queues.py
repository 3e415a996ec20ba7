"""Queues per kind of job: a refinement submitted while a big basis job runs starts on the refinement worker.

Starts a private ``redis-server``, one API process on it and one worker per queue as docker-compose does
(``--queues curvefm-basis`` and ``--queues curvefm-refine``), all on a temporary data directory. Uploads a FAUST pair
(bases at ``--pair-k``, a session with three curves) and FAUST tr_reg_000 subdivided ``--level`` times (3: 440,834
vertices), starts that mesh's basis at ``--k``, and once it computes the eigenpairs submits a refinement of the pair:
``start_delay_s`` is from the refinement's request to its start on the worker, ``basis_state_then`` says the basis
job still ran. The basis job is canceled at the end. Prints JSON. Target (issue 32): a start within 5 s.

Usage: ``python -m benchmarks.bench_queues [--level 3] [--k 120] [--pair-k 30]``
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import trimesh

from benchmarks.bench_scan import PAIR, subdivided
from benchmarks.common import machine, shared_data, start_server

ENDED = ("finished", "failed", "canceled", "lost")
KINDS = ("basis", "refine")
EIGENSOLVER_PROGRESS = 0.05  # where a basis job reports that it computes the eigenpairs


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_redis(folder: Path) -> tuple[subprocess.Popen, str]:
    if shutil.which("redis-server") is None:
        sys.exit("the benchmark needs redis-server (Debian's redis-server)")
    port = free_port()
    command = ["redis-server", "--port", str(port), "--bind", "127.0.0.1", "--save", "", "--dir", str(folder)]
    redis = subprocess.Popen(command, stdout=subprocess.DEVNULL)
    url = f"redis://127.0.0.1:{port}/0"
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return redis, url
        time.sleep(0.05)
    redis.kill()
    sys.exit("redis-server did not start")


def start_worker(queue: str, redis_url: str, log: Path) -> subprocess.Popen:
    command = [sys.executable, "-m", "curvefm.workers", "--redis-url", redis_url, "--queues", queue]
    return subprocess.Popen(command, stdout=open(log, "ab"), stderr=subprocess.STDOUT)  # noqa: SIM115


def upload(client: httpx.Client, path: Path) -> str:
    with open(path, "rb") as f:
        return client.post("/shapes", files={"file": (path.name, f)}, timeout=600).raise_for_status().json()["id"]


def wait(client: httpx.Client, job_id: str, until=ENDED, timeout: float = 3600) -> dict:
    deadline = time.monotonic() + timeout
    while (info := client.get(f"/jobs/{job_id}").raise_for_status().json())["state"] not in until:
        if time.monotonic() > deadline:
            sys.exit(f"job {job_id} still {info['state']} after {timeout} s")
        time.sleep(0.05)
    return info


def prepare_session(client: httpx.Client, k: int) -> str:
    """The FAUST pair with bases at ``k`` and a session with three curves (FAUST vertices correspond by index)."""
    ids = [upload(client, shared_data() / "faust" / f"{name}.off") for name in PAIR]
    for shape_id in ids:
        job = client.post(f"/shapes/{shape_id}/bases", json={"k": k}).raise_for_status().json()
        assert wait(client, job["id"])["state"] == "finished"
    session = client.post("/sessions", json={"source": ids[0], "target": ids[1], "k": k}).raise_for_status().json()
    for a, b in ((412, 5120), (1500, 3300), (6000, 240)):
        client.post(f"/sessions/{session['id']}/curves", json={"source": [a, b], "target": [a, b]}).raise_for_status()
    return session["id"]


def big_mesh(folder: Path, level: int) -> tuple[Path, int]:
    mesh = subdivided(PAIR[0], level)
    path = folder / f"{PAIR[0]}-subdivided-{level}.ply"
    trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(path)
    return path, len(mesh.vertices)


def measure(client: httpx.Client, args, folder: Path) -> dict:
    session_id = prepare_session(client, args.pair_k)
    path, vertices = big_mesh(folder, args.level)
    big_id = upload(client, path)
    basis = client.post(f"/shapes/{big_id}/bases", json={"k": args.k}).raise_for_status().json()
    while (running := client.get(f"/jobs/{basis['id']}").json())["progress"] < EIGENSOLVER_PROGRESS:
        if running["state"] in ENDED:
            sys.exit(f"the basis job ended before the refinement: {running}")
        time.sleep(0.1)
    time.sleep(args.settle)  # into the eigensolver: the work horse has its memory and the cores
    load_then = os.getloadavg()[0]
    submitted = time.time()
    refinement = client.post(f"/sessions/{session_id}/refine", json={}).raise_for_status().json()
    started = wait(client, refinement["id"], until=("started", *ENDED))
    basis_then = client.get(f"/jobs/{basis['id']}").json()
    refined = wait(client, refinement["id"])
    client.delete(f"/jobs/{basis['id']}")
    wait(client, basis["id"])  # its work horse stopped: nothing outlives the benchmark
    return {
        "basis_vertices": vertices,
        "basis_k": args.k,
        "basis_state_then": basis_then["state"],
        "basis_progress_then": basis_then["progress"],
        "refinement_state": refined["state"],
        "refinement_worker": refined["worker"],
        "basis_worker": basis_then["worker"],
        "load_1min_then": round(load_then, 1),
        "start_delay_s": round(started["started_at"] - submitted, 3),
        "refinement_run_s": round(refined["ended_at"] - refined["started_at"], 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--level", type=int, default=3, help="subdivisions of FAUST tr_reg_000 (3: 440,834 vertices)")
    parser.add_argument("--k", type=int, default=120, help="basis size of the big job")
    parser.add_argument("--pair-k", type=int, default=30, help="basis size of the refined pair")
    parser.add_argument("--settle", type=float, default=3.0, help="seconds into the eigensolver before refining")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="curvefm-bench-queues-") as temporary:
        folder = Path(temporary)
        redis, redis_url = start_redis(folder)
        processes = [redis]
        try:
            processes += [start_worker(f"curvefm-{kind}", redis_url, folder / f"{kind}.log") for kind in KINDS]
            server, url, headers = start_server(folder / "data", ("--rate-limit", "0", "--redis-url", redis_url))
            processes.append(server)
            with httpx.Client(base_url=url, headers=headers, timeout=60) as client:
                result = measure(client, args, folder)
        finally:
            for process in reversed(processes):
                process.kill()
                process.wait()
    print(json.dumps({"benchmark": "queues", **machine(), **result}, indent=2))


if __name__ == "__main__":
    main()
