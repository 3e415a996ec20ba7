"""A FAUST collection solved and refined in batch on two worker processes against a real server with Redis.

The template is FAUST's tr_reg_000; the members are the other registrations under ``<shared>/faust`` (19 of
them, ``--members`` takes the first N). FAUST registrations share vertex ids, so the ground truth is the
identity. Template curves are ``curvefm reproduce``'s: :func:`ground_truth_curves` (``--curves`` paths between
paired farthest points); each member answers every template curve through the API with its own side of that
protocol (the geodesic path between the same vertex ids on the member), as a script would.

Starts a private ``redis-server`` on a free port (or uses ``$CURVEFM_REDIS_URL``) with a unique queue prefix,
``curvefm serve`` on it and two ``curvefm worker`` processes, and measures:

- ``bases``: wall time from creating the collection (which queues the template's and members' basis jobs) to
  every basis being ready, on the two workers (near zero when ``--data`` already holds them: ``cached``);
- ``runs``: per converter (``--converter``, default ``zoomout``, and ``nearest-neighbor`` unless
  ``--no-nearest``) the batch run's wall time (``POST .../runs`` to every member finished), and per member the
  mean geodesic error / sqrt(area) of the archive's maps, template -> member (on the member) and back (on the
  template);
- ``composed``: for ``--pairs`` seeded member pairs (a, b), the map a -> b through the template
  (``GET .../members/{a}/to/{b}``) against the ground truth, next to the worse of its two direct maps
  (a -> template, template -> b).

Usage: ``python -m benchmarks.bench_collection [--members 19] [--curves 10] [--converter zoomout] [--k 120]
[--pairs 5] [--no-nearest] [--data DIR]``. Prints JSON.
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
import uuid
from contextlib import ExitStack, contextmanager
from pathlib import Path

import numpy as np

from benchmarks.common import machine, shared_data, start_server
from curvefm.client import Client
from curvefm.evaluation import evaluate_map, ground_truth_curves, identity_truth
from curvefm.geometry import Mesh, load_mesh

TEMPLATE = "tr_reg_000.off"
WORKERS = ("w1", "w2")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextmanager
def running(command: list[str], log: Path, env: dict[str, str] | None = None):
    """A child process (output to ``log``), killed on exit."""
    with open(log, "ab") as output:
        process = subprocess.Popen(command, stdout=output, stderr=subprocess.STDOUT, env={**os.environ, **(env or {})})
    try:
        yield process
    finally:
        process.kill()
        process.wait(timeout=30)


@contextmanager
def redis_url(stack: ExitStack, logs: Path):
    """``$CURVEFM_REDIS_URL``, or a private redis-server without persistence on a free port."""
    if url := os.environ.get("CURVEFM_REDIS_URL"):
        yield url
        return
    import redis

    port = free_port()
    command = ["redis-server", "--port", str(port), "--bind", "127.0.0.1", "--save", "", "--appendonly", "no"]
    stack.enter_context(running(command, logs / "redis.log"))
    url = f"redis://127.0.0.1:{port}/0"
    deadline = time.monotonic() + 20
    while True:
        try:
            redis.Redis.from_url(url, socket_connect_timeout=1).ping()
            break
        except redis.RedisError:
            if time.monotonic() > deadline:
                raise SystemExit("redis-server did not start") from None
            time.sleep(0.05)
    yield url


def start_services(stack: ExitStack, data: Path, logs: Path) -> Client:
    """Redis, two workers and the API on ``data`` (one queue prefix for all); a client of the user ``bench``."""
    url = stack.enter_context(redis_url(stack, logs))
    prefix = f"bench-coll-{uuid.uuid4().hex[:8]}-"
    env = {"CURVEFM_QUEUE_PREFIX": prefix}
    for name in WORKERS:
        command = [sys.executable, "-m", "curvefm.workers", "--redis-url", url, "--name", f"{prefix}{name}"]
        stack.enter_context(running(command, logs / f"worker-{name}.log", env))
    server, base, headers = start_server(data, ("--rate-limit", "0", "--redis-url", url), env, logs / "api.log")
    stack.callback(server.wait, 30)
    stack.callback(server.kill)
    token = headers["Authorization"].removeprefix("Bearer ")
    return stack.enter_context(Client(base, token, timeout=300))


def file_ids(mesh: Mesh, path: np.ndarray) -> list[int]:
    return mesh.file_ids[path].tolist()


def internal_map(p2p_file: np.ndarray, mesh_X: Mesh, mesh_Y: Mesh) -> np.ndarray:
    """A pointwise map X -> Y in file ids (as the archive holds it) in internal ids."""
    return mesh_Y.internal_ids(np.asarray(p2p_file)[mesh_X.file_ids], "mapped vertex")


def error(p2p_file: np.ndarray, mesh_X: Mesh, mesh_Y: Mesh) -> float:
    """Mean geodesic error / sqrt(area of Y) of a map X -> Y against FAUST's identity ground truth."""
    truth = identity_truth(mesh_X, mesh_Y)
    return round(evaluate_map(internal_map(p2p_file, mesh_X, mesh_Y), truth, mesh_Y).mean_area, 5)


def make_collection(client: Client, paths: list[Path], meshes: list[Mesh], curves: list, k: int):
    """Upload the shapes, create the collection (the template curves as explicit paths) and wait for every
    basis: (collection, member id per member index, bases wall time, whether every basis was already stored)."""
    template, *members = (client.upload(path) for path in paths)
    specs = [
        {"name": f"gt{n}", "waypoints": file_ids(meshes[0], path_T), "explicit": True}
        for n, (path_T, _) in enumerate(curves[0], 1)
    ]
    start = time.perf_counter()
    collection = client.collection(template, curves=specs, members=members, k=k, name="faust-bench")
    cached = all(m["basis_job"] is None for m in collection.info["members"])
    collection.wait_bases()
    client.basis(template, k).wait(progress=False)
    bases_s = time.perf_counter() - start
    ids = {m["shape"]: m["id"] for m in collection.info["members"]}
    return collection, [ids[shape] for shape in members], bases_s, cached


def answer_curves(collection, member_ids: list[str], meshes: list[Mesh], curves: list) -> float:
    """Every member answers every template curve with its side of the ground-truth curves; the wall time."""
    start = time.perf_counter()
    for member, mesh, member_curves in zip(member_ids, meshes[1:], curves, strict=True):
        for n, (_, path_N) in enumerate(member_curves, 1):
            collection.answer(member, f"t{n}", file_ids(mesh, path_N), explicit=True)
    return time.perf_counter() - start


def spread(values: list[float]) -> dict:
    return {
        "mean": round(float(np.mean(values)), 5),
        "median": round(float(np.median(values)), 5),
        "max": round(float(np.max(values)), 5),
    }


def batch_run(collection, converter: str, member_ids: list[str], meshes: list[Mesh], pairs, scratch: Path) -> dict:
    """One batch run of every member: its wall time, per member errors both ways, and the composed pairs."""
    start = time.perf_counter()
    run = collection.wait_run(collection.run(converter)["id"])
    wall_s = time.perf_counter() - start
    workers = {collection.client.json("GET", f"/jobs/{m['job']}")["worker"] for m in run["members"]}
    archive = np.load(collection.archive(run["id"], scratch / f"{converter}.npz"))
    template, members = meshes[0], dict(zip(member_ids, meshes[1:], strict=True))
    errors = {
        m: {
            "template_to_member": error(archive[f"{m}/map_template_to_member"], template, mesh),
            "member_to_template": error(archive[f"{m}/map_member_to_template"], mesh, template),
        }
        for m, mesh in members.items()
    }
    composed = []
    for a, b in pairs:
        p2p, _ = collection.composed(run["id"], a, b)
        direct = max(errors[a]["member_to_template"], errors[b]["template_to_member"])
        composed.append({"a": a, "b": b, "error": error(p2p, members[a], members[b]), "worse_direct": direct})
    both_ways = [e for member in errors.values() for e in member.values()]
    return {
        "converter": converter,
        "wall_s": round(wall_s, 1),
        "per_member_s": round(wall_s / len(member_ids), 2),
        "workers_used": len(workers),
        "error_both_ways": spread(both_ways),
        "members": errors,
        "composed": composed,
        "composed_error": spread([c["error"] for c in composed]),
        "composed_over_worse_direct": spread([c["error"] / c["worse_direct"] for c in composed]),
    }


def seeded_pairs(member_ids: list[str], count: int, seed: int = 0) -> list[tuple[str, str]]:
    """``count`` distinct ordered pairs of different members, the same for the same seed."""
    rng, chosen = np.random.default_rng(seed), {}
    while len(chosen) < min(count, len(member_ids) * (len(member_ids) - 1)):
        a, b = rng.choice(len(member_ids), size=2, replace=False)
        chosen[(member_ids[a], member_ids[b])] = None
    return list(chosen)


def faust_shapes(count: int) -> list[Path]:
    """The template, then the first ``count`` other FAUST registrations."""
    folder = shared_data() / "faust"
    others = sorted(p for p in folder.glob("tr_reg_*.off") if p.name != TEMPLATE)
    if count > len(others):
        sys.exit(f"{folder} holds {len(others)} members besides {TEMPLATE}, not {count}")
    return [folder / TEMPLATE, *others[:count]]


def benchmark(args, data: Path) -> dict:
    paths = faust_shapes(args.members)
    meshes = [load_mesh(path) for path in paths]
    curves = [ground_truth_curves(meshes[0], mesh, identity_truth(meshes[0], mesh), args.curves) for mesh in meshes[1:]]
    converters = [args.converter] + (
        [] if args.no_nearest or args.converter == "nearest-neighbor" else ["nearest-neighbor"]
    )
    logs = data / "bench-logs"
    logs.mkdir(parents=True, exist_ok=True)
    with ExitStack() as stack:
        client = start_services(stack, data, logs)
        collection, member_ids, bases_s, cached = make_collection(client, paths, meshes, curves, args.k)
        answers_s = answer_curves(collection, member_ids, meshes, curves)
        pairs = seeded_pairs(member_ids, args.pairs)
        scratch = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="curvefm-bench-coll-")))
        runs = [batch_run(collection, converter, member_ids, meshes, pairs, scratch) for converter in converters]
    return {
        "benchmark": "collection",
        "template": TEMPLATE,
        "members": len(member_ids),
        "vertices": meshes[0].n_vertices,
        "curves": args.curves,
        "k": args.k,
        "workers": len(WORKERS),
        "bases": {"wall_s": round(bases_s, 1), "cached": cached, "jobs": 0 if cached else len(member_ids) + 1},
        "answers": {
            "wall_s": round(answers_s, 1),
            "per_curve_ms": round(1e3 * answers_s / len(member_ids) / args.curves, 1),
        },
        "error": "mean geodesic error / sqrt(area of the map's target), FAUST identity ground truth",
        "runs": runs,
        "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
        **machine(),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--members", type=int, default=19)
    parser.add_argument("--curves", type=int, default=10)
    parser.add_argument("--converter", default="zoomout")
    parser.add_argument("--no-nearest", action="store_true", help="skip the nearest-neighbor run")
    parser.add_argument("--k", type=int, default=120)
    parser.add_argument("--pairs", type=int, default=5, help="seeded member pairs composed through the template")
    parser.add_argument("--data", type=Path, help="data directory kept between runs (bases are reused)")
    args = parser.parse_args()
    if args.data:
        print(json.dumps(benchmark(args, args.data), indent=2))
        return
    data = Path(tempfile.mkdtemp(prefix="curvefm-bench-coll-data-"))
    try:
        print(json.dumps(benchmark(args, data), indent=2))
    finally:
        shutil.rmtree(data, ignore_errors=True)


if __name__ == "__main__":
    main()
