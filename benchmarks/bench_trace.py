"""Curve tracing on a 30k-vertex mesh (TOSCA cat0, 27894 vertices): median trace time of each tracer.

Budget (docs/performance.md): trace a curve on a 30k-vertex mesh in <= 30 ms. Two sets of seeded endpoint pairs:
``random`` (uniform over the mesh: mostly far apart, the worst case) and ``short`` (edge-path distance 5-25%
of the bounding-box diagonal: what a person clicks for one feature curve). The anisotropic tracer's first
call on a mesh builds its feature field and weighted graph (``build_s``); traces after that reuse them.

``--subdivide N`` traces on the mesh subdivided N times (``trimesh.remesh.subdivide``, generated at run time and
never written): FAUST tr_reg_000 subdivided 3 times has 440,834 vertices, where the budget is 50 ms (issue 14).

``--guided`` (issue 37) compares, on the subdivided mesh, the geodesic tracer on the whole mesh with its search
near the mesh's display copy (``run_guided``, what live sessions do on shapes of millions of vertices), for
``--pairs`` seeded pairs of the mesh's original vertices (the ones before subdividing, as a person clicks them on
the display copy: ``random``) and the ``short`` set: both times, and the guided path's length against the
whole-mesh shortest path's. The display copy (``--display-vertices``, default 50,000) is read from the
benchmarks' store (``CURVEFM_BENCH_DATA``) or made and stored there; the anisotropic tracer is skipped.

``--edits`` (with ``--subdivide N``) times the trace part of ``bench_ui_latency``'s edits on FAUST tr_reg_000 ->
tr_reg_011 subdivided N times: for each of its curves between original vertices, the two traces (one a shape), on
the whole meshes and guided, without bases (at 1.76M vertices they take 25 minutes a shape here).

Usage: ``python -m benchmarks.bench_trace [MESH] [--subdivide N] [--pairs N] [--seed S] [--guided] [--edits]``; prints
JSON.
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

from benchmarks.bench_scan import subdivided
from benchmarks.bench_ui_latency import EDITS, SCAN_PAIR
from benchmarks.common import bench_store
from curvefm.geometry import build_mesh, display_graph, load_mesh
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


def _path_length(mesh, path: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(mesh.vertices[path], axis=0), axis=1).sum())


def _spread(ms: list[float]) -> dict:
    return {"median": round(float(np.median(ms)), 1), "p95": round(float(np.percentile(ms, 95)), 1)}


def _guided(mesh, pairs: dict[str, np.ndarray], display_vertices: int) -> dict:
    t0 = time.perf_counter()
    guide = _stored_guide(mesh, display_vertices)
    out: dict = {
        "display_vertices": len(guide.vertex_ids),
        "display_read_or_made_s": round(time.perf_counter() - t0, 2),
    }
    t0 = time.perf_counter()
    guide.cells, display_graph(mesh, guide)  # noqa: B018 - what a live session prepares when it loads
    out["guide_prep_s"] = round(time.perf_counter() - t0, 3)
    params = tracers.GEODESIC.parse_params({})
    for name, endpoints in pairs.items():
        full_ms, guided_ms, excess, same = [], [], [], 0
        for start, end in endpoints.tolist():
            t0 = time.perf_counter()
            whole = tracers.trace_geodesic(mesh, start, end, params)
            t1 = time.perf_counter()
            near = tracers.trace_geodesic_guided(mesh, start, end, params, guide)
            t2 = time.perf_counter()
            full_ms.append(1e3 * (t1 - t0))
            guided_ms.append(1e3 * (t2 - t1))
            excess.append(_path_length(mesh, near) / max(_path_length(mesh, whole), 1e-300) - 1.0)
            same += int(np.array_equal(whole, near))
        pct = 100 * np.array(excess)
        out[name] = {
            "full_ms": _spread(full_ms),
            "guided_ms": _spread(guided_ms),
            "length_excess_pct": {"mean": round(float(pct.mean()), 4), "max": round(float(pct.max()), 4)},
            "identical_paths": same,
        }
    return out


def _stored_guide(mesh, display_vertices: int):
    store = bench_store()
    store.put_mesh(mesh)
    return store.ensure_display(mesh, display_vertices)


def _edit_traces(level: int, display_vertices: int) -> dict:
    """Both traces of each of bench_ui_latency's edits, whole and guided, on the FAUST pair subdivided ``level``."""
    meshes = [subdivided(name, level) for name in SCAN_PAIR]
    guides = [_stored_guide(mesh, display_vertices) for mesh in meshes]
    for mesh, guide in zip(meshes, guides, strict=True):
        mesh.edge_graph, guide.cells, display_graph(mesh, guide)  # noqa: B018 - what a live session prepares
    params = tracers.GEODESIC.parse_params({})
    whole_ms, guided_ms = [], []
    for start, end in EDITS:
        t0 = time.perf_counter()
        for mesh in meshes:
            tracers.trace_geodesic(mesh, start, end, params)
        t1 = time.perf_counter()
        for mesh, guide in zip(meshes, guides, strict=True):
            tracers.trace_geodesic_guided(mesh, start, end, params, guide)
        whole_ms.append(round(1e3 * (t1 - t0), 1))
        guided_ms.append(round(1e3 * (time.perf_counter() - t1), 1))
    return {"vertices": meshes[0].n_vertices, "edits": len(EDITS), "whole_ms": whole_ms, "guided_ms": guided_ms}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mesh", nargs="?", default=str(DEFAULT_MESH))
    parser.add_argument("--pairs", type=int, default=50)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--builds", type=int, default=3, help="cold anisotropic builds to take the median of")
    parser.add_argument("--subdivide", type=int, default=0, help="subdivide the mesh this many times first")
    parser.add_argument("--guided", action="store_true", help="the whole-mesh trace against the guided one")
    parser.add_argument("--display-vertices", type=int, default=50_000)
    parser.add_argument("--edits", action="store_true", help="the traces of bench_ui_latency's edits, both shapes")
    args = parser.parse_args()
    if args.edits:
        result = {"benchmark": "trace --edits", **_edit_traces(args.subdivide, args.display_vertices)}
        result |= {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "load": os.getloadavg()}
        print(json.dumps(result))
        return
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

    if args.guided:
        original = len(load_mesh(args.mesh).vertices)  # subdividing keeps them first, with their ids
        pairs = _pairs(mesh, args.pairs, args.seed)
        pairs["random"] = np.random.default_rng(args.seed).integers(0, original, (args.pairs, 2))
        result = {"benchmark": "trace --guided", "mesh": Path(args.mesh).name, "vertices": mesh.n_vertices}
        result |= _guided(mesh, pairs, args.display_vertices)
        result |= {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "load": os.getloadavg()}
        print(json.dumps(result, indent=2))
        return

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
