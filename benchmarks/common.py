"""Shared helpers of the benchmarks and the experiments: data location, cached bases, scoring maps, the machine,
timing, a server.

Run both from the repository root as modules (``python -m benchmarks.bench_trace``, ``python -m experiments.alpha``),
so that ``benchmarks`` and ``experiments`` are packages and this module is ``benchmarks.common``."""

import contextlib
import os
import platform
import secrets
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from datetime import date
from pathlib import Path

import httpx

from curvefm.access import users_of
from curvefm.errors import Conflict
from curvefm.evaluation import GroundTruth, score_maps, truth_to_score
from curvefm.evaluation.protocol import DIRECTIONS, Curves
from curvefm.pointwise import PointwiseMaps
from curvefm.spectral import ShapePair
from curvefm.store import Store

REPO = Path(__file__).resolve().parents[1]


def shared_data() -> Path:
    path = Path(os.environ.get("CURVEFM_SHARED_DATA", REPO.parent / "shared" / "data"))
    if not path.is_dir():
        sys.exit(f"benchmark needs the shared data folder {path} (set CURVEFM_SHARED_DATA)")
    return path


def bench_store() -> Store:
    """Bases cached between benchmark runs (``CURVEFM_BENCH_DATA``, default /tmp/curvefm-bench)."""
    return Store(os.environ.get("CURVEFM_BENCH_DATA", "/tmp/curvefm-bench"))


def handed_out_errors(
    pair: ShapePair, maps: PointwiseMaps, truth: GroundTruth, curves: Curves, directions: Sequence[str] = DIRECTIONS
) -> dict[str, float]:
    """How bench_suggestions and bench_monotone score a map: the mean geodesic error / sqrt(area) of ``maps`` (what
    ``curvefm match`` hands out: its result's maps, or :func:`curvefm.matching.handed_out` of the functional maps)
    in each of ``directions``, at the ground-truth rows :func:`curvefm.evaluation.truth_to_score` keeps (none at a
    curve's end on either shape; of a landmark truth, only the landmarks held out of the endpoints); with both
    directions, also their ``mean``."""
    errors = score_maps(pair, maps, truth_to_score(truth, curves), directions)
    scored = {direction: round(e["mean_area"], 6) for direction, e in errors.items()}
    if len(scored) == len(DIRECTIONS):
        scored["mean"] = round(sum(scored.values()) / len(scored), 6)
    return scored


def machine() -> dict:
    return {
        "date": date.today().isoformat(),
        "cpus": os.cpu_count(),
        "machine": platform.machine(),
        "python": platform.python_version(),
    }


def median_ms(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def median_wall_and_cpu_ms(fn, repeat: int) -> tuple[float, float]:
    """Median wall-clock and median CPU milliseconds of ``fn`` (CPU: all of the process's threads). On a machine
    shared with other work the CPU time is the steadier of the two."""
    walls, cpus = [], []
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        fn()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return 1e3 * statistics.median(walls), 1e3 * statistics.median(cpus)


def bench_token(data: Path) -> str:
    """A token of the user ``bench`` on the data directory (made, or rotated when it exists)."""
    users = users_of(data)
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


@contextlib.contextmanager
def scratch_database(engine: str, postgres: str) -> Iterator[str]:
    """The URL of a new, empty records database: a SQLite file in a temporary folder, or a database
    ``curvefm_bench_<random>`` made on the PostgreSQL server ``postgres`` and dropped afterwards."""
    if engine == "sqlite":
        with tempfile.TemporaryDirectory() as folder:
            yield f"sqlite:///{folder}/curvefm.db"
        return
    import psycopg

    name = f"curvefm_bench_{secrets.token_hex(6)}"
    with psycopg.connect(postgres, autocommit=True) as admin:
        admin.execute(f'CREATE DATABASE "{name}"')
        try:
            yield f"{postgres.rsplit('/', 1)[0].replace('postgresql://', 'postgresql+psycopg://', 1)}/{name}"
        finally:
            admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
