"""Curve tracing on a 30k-vertex mesh (TOSCA cat0, 27894 vertices): median trace time of each tracer.

Budget (docs/performance.md): trace a curve on a 30k-vertex mesh in <= 30 ms. Two sets of seeded endpoint pairs:
``random`` (uniform over the mesh: mostly far apart, the worst case) and ``short`` (edge-path distance 5-25%
of the bounding-box diagonal: what a person clicks for one feature curve). The anisotropic tracer's first
call on a mesh builds its feature field and weighted graph (``build_s``); traces after that reuse them.

``--subdivide N`` traces on the mesh subdivided N times (``trimesh.remesh.subdivide``, generated at run time and
never written): FAUST tr_reg_000 subdivided 3 times has 440,834 vertices, where the budget is 50 ms (issue 14).

Usage: ``python -m benchmarks.bench_trace [MESH] [--subdivide N] [--pairs N] [--seed S]``; prints JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import trimesh
from scipy.sparse.csgraph import dijkstra

from curvefm.geometry import build_mesh, load_mesh
from curvefm.plugins import tracers
from curvefm.runtime import limit_blas_threads

DEFAULT_MESH = Path(__file__).resolve().parents[2] / "shared" / "data" / "tosca" / "cat0.off"


def _pairs(mesh, count: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    random_pairs = rng.integers(0, mesh.n_vertices, (count, 2))
    diag = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    short = []
    while len(short) < count:
        start = int(rng.integers(mesh.n_vertices))
        dist = dijkstra(mesh.edge_graph, directed=True, indices=start, limit=0.25 * diag)
        candidates = np.flatnonzero(np.isfinite(dist) & (dist > 0.05 * diag))
        if len(candidates):
            short.append((start, int(rng.choice(candidates))))
    return {"random": random_pairs, "short": np.array(short)}


def _time_traces(plugin, mesh, pairs: np.ndarray, params) -> dict:
    times = []
    for start, end in pairs:
        t0 = time.perf_counter()
        plugin.run(mesh, int(start), int(end), params)
        times.append(time.perf_counter() - t0)
    ms = 1e3 * np.array(times)
    return {"median_ms": round(float(np.median(ms)), 2), "p95_ms": round(float(np.percentile(ms, 95)), 2)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mesh", nargs="?", default=str(DEFAULT_MESH))
    parser.add_argument("--pairs", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--builds", type=int, default=3, help="cold anisotropic builds to take the median of")
    parser.add_argument("--subdivide", type=int, default=0, help="subdivide the mesh this many times first")
    args = parser.parse_args()
    if not Path(args.mesh).is_file():
        raise SystemExit(f"mesh not found: {args.mesh} (the shared data folder is described in its README)")

    t0 = time.perf_counter()
    mesh = load_mesh(args.mesh)
    load_s = time.perf_counter() - t0
    if args.subdivide:
        vertices, faces = mesh.vertices, mesh.faces
        for _ in range(args.subdivide):
            vertices, faces = trimesh.remesh.subdivide(vertices, faces)
        mesh = build_mesh(vertices, faces, name=f"{mesh.name} subdivided {args.subdivide}x")
    t0 = time.perf_counter()
    mesh.edge_graph, mesh.content_hash  # noqa: B018 - per-mesh work any session does once at load
    mesh_prep_s = time.perf_counter() - t0

    params = tracers.ANISOTROPIC.parse_params({})
    builds = []
    for _ in range(args.builds):
        mesh.derived.clear()
        t0 = time.perf_counter()
        tracers.anisotropic_graph(mesh, params)
        builds.append(time.perf_counter() - t0)

    pairs = _pairs(mesh, args.pairs, args.seed)
    result = {
        "benchmark": "trace",
        "mesh": Path(args.mesh).name,
        "subdivisions": args.subdivide,
        "vertices": mesh.n_vertices,
        "pairs_per_set": args.pairs,
        "seed": args.seed,
        "load_s": round(load_s, 3),
        "edge_graph_and_hash_s": round(mesh_prep_s, 3),
        "anisotropic_build_s": round(float(np.median(builds)), 3),
        "anisotropic_params": params.model_dump(),
        "budget_ms": 50 if mesh.n_vertices > 100_000 else 30,
    }
    for plugin, p in ((tracers.GEODESIC, tracers.GEODESIC.parse_params({})), (tracers.ANISOTROPIC, params)):
        plugin.run(mesh, 0, 1, p)  # warm (the anisotropic graph is cached from the builds above)
        result[plugin.name] = {name: _time_traces(plugin, mesh, pp, p) for name, pp in pairs.items()}
    result["machine"] = {"platform": platform.platform(), "cpus": os.cpu_count()}
    result["date"] = time.strftime("%Y-%m-%d")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    limit_blas_threads()
    main()
