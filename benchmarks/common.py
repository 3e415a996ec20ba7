"""Shared helpers for the benchmarks: data location, cached bases, timing."""

import argparse
import itertools
import os
import platform
import socket
import statistics
import subprocess
import sys
import time
from datetime import date
from pathlib import Path

import httpx

from curvefm.access import UserStore
from curvefm.errors import Conflict
from curvefm.evaluation import ground_truth_for
from curvefm.evaluation.reproduce.datasets import DATASETS, FULL_PAIRS, Pair
from curvefm.geometry import load_mesh
from curvefm.spectral import ShapePair
from curvefm.store import Store

REPO = Path(__file__).resolve().parents[1]
HELD_OUT_PAIRS = (  # pairs the reproduce suite does not hold, to check rules chosen on it
    Pair("faust", "faust/tr_reg_060.off", "faust/tr_reg_071.off"),
    Pair("faust", "faust/tr_reg_080.off", "faust/tr_reg_091.off"),
    Pair("faust", "faust/tr_reg_010.off", "faust/tr_reg_051.off"),
    Pair("tosca", "tosca/dog0.off", "tosca/dog2.off"),
    Pair("tosca", "tosca/horse0.off", "tosca/horse5.off"),
    Pair("tosca", "tosca/gorilla1.off", "tosca/gorilla5.off"),
    Pair("tosca", "tosca/michael0.off", "tosca/michael1.off"),
    Pair("tosca-cross", "tosca/cat0.off", "tosca/dog0.off"),
    Pair("tosca-cross", "tosca/horse0.off", "tosca/wolf0.off"),
    Pair("tosca-cross", "tosca/dog2.off", "tosca/horse5.off"),
    Pair("tosca-cross", "tosca/michael0.off", "tosca/gorilla5.off"),
    Pair("tosca-cross", "tosca/victoria0.off", "tosca/david1.off"),
)


def add_pair_arguments(parser: argparse.ArgumentParser) -> None:
    """``--pairs suite|held-out`` (the reproduce suite's pairs or :data:`HELD_OUT_PAIRS`) and ``--datasets``."""
    parser.add_argument("--pairs", choices=("suite", "held-out"), default="suite")
    parser.add_argument("--datasets", nargs="+", default=list(DATASETS), choices=list(DATASETS))


def chosen_pairs(args: argparse.Namespace) -> list[Pair]:
    """The pairs :func:`add_pair_arguments`'s options select."""
    return [p for p in (FULL_PAIRS if args.pairs == "suite" else HELD_OUT_PAIRS) if p.dataset in args.datasets]


def shared_data() -> Path:
    path = Path(os.environ.get("CURVEFM_SHARED_DATA", REPO.parent / "shared" / "data"))
    if not path.is_dir():
        sys.exit(f"benchmark needs the shared data folder {path} (set CURVEFM_SHARED_DATA)")
    return path


def bench_store() -> Store:
    """Bases cached between benchmark runs (``CURVEFM_BENCH_DATA``, default /tmp/curvefm-bench)."""
    return Store(os.environ.get("CURVEFM_BENCH_DATA", "/tmp/curvefm-bench"))


def ground_truth_pair(source: str, target: str, k: int = 120):
    """``(ShapePair, GroundTruth)`` for two meshes of the shared data folder (paths relative to it), with
    bases of k functions from :func:`bench_store`."""
    data, store = shared_data(), bench_store()
    M, N = load_mesh(data / source), load_mesh(data / target)
    truth = ground_truth_for(data / source, data / target, M, N)
    return ShapePair(M, N, store.ensure_basis(M, k), store.ensure_basis(N, k)), truth


def ground_truth_rows(pairs, counts, errors_for) -> list[dict]:
    """``{"pair", "curves", "errors"}`` per pair and curve count, ``errors = errors_for(pair, truth, curves)`` for
    ``curvefm evaluate``'s ground-truth curves (2n farthest points among the vertices with a known partner,
    consecutive pairs joined); progress on stderr."""
    from curvefm.evaluation import ground_truth_curves

    rows = []
    for (source, target), count in itertools.product(pairs, counts):
        pair, truth = ground_truth_pair(source, target)
        curves = ground_truth_curves(pair.mesh_M, pair.mesh_N, truth, count)
        rows.append({"pair": f"{source} -> {target}", "curves": count, "errors": errors_for(pair, truth, curves)})
        print(f"{source} -> {target}, {count} curves done", file=sys.stderr, flush=True)
    return rows


def machine() -> dict:
    return {"date": date.today().isoformat(), "cpus": os.cpu_count(), "machine": platform.machine(),
            "python": platform.python_version()}


def median_ms(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def bench_token(data: Path) -> str:
    """A token of the user ``bench`` on the data directory (made, or rotated when it exists)."""
    users = UserStore(data)
    try:
        return users.add("bench")
    except Conflict:
        return users.rotate("bench")


def start_server(
    data: Path,
    args: tuple[str, ...] = ("--rate-limit", "0"),
    env: dict[str, str] | None = None,
    log: Path | None = None,
) -> tuple[subprocess.Popen, str, dict[str, str]]:
    """``curvefm serve`` (embedded jobs unless ``args`` name a Redis) on a free port with data in ``data``:
    (process, base url, the headers that authenticate a request as the user ``bench``). By default without a
    rate limit: benchmarks load the server from one client. Its output goes to ``log`` (default: nowhere)."""
    headers = {"Authorization": f"Bearer {bench_token(data)}"}
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    command = [sys.executable, "-m", "curvefm.service", "--port", str(port), "--data", str(data), *args]
    environment = {**os.environ, **(env or {})}
    output = open(log, "ab") if log else subprocess.DEVNULL  # noqa: SIM115  (the child holds it)
    server = subprocess.Popen(command, env=environment, stdout=output, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            if httpx.get(f"{url}/health", timeout=1).status_code == 200:
                return server, url, headers
        except httpx.TransportError:
            time.sleep(0.1)
    server.kill()
    raise SystemExit("the server did not start")
