"""Nearest neighbours, exact and approximate, in the embeddings the converters search (prints JSON).

* ``spectral``: TOSCA cat0 -> cat1 (27,894 vertices each): data ``Phi_k C^T``, queries ``Psi_k``, with C the
  functional map of the true correspondence, k = 50 and 120 (the design budget: 30k x 30k in 120 dimensions).
* ``zoomout``: FAUST tr_reg_000 -> 011 (6,890 vertices) at the sizes ZoomOut steps through (20 to 120).
* ``rhm``: FAUST, the 16-dimensional stacked geodesic-MDS embeddings RHM projects in (from 10-curve maps).

* ``scan``: FAUST tr_reg_000 -> 011 subdivided 1 / 2 / 3 times (27,554 / 110,210 / 440,834 vertices, as
  benchmarks/bench_scan.py makes them; the pair shares its connectivity, so the identity is the true map) in
  20, 60 and 120 dimensions: exact search against the approximate one (:mod:`curvefm.pointwise.neighbors`:
  faiss IVF) and, with ``--hnsw``, faiss HNSW (32 links, efSearch 64 and 256), the alternative it was chosen
  over. Exact search answers ``--recall-queries`` random queries (its time extrapolated linearly to all of
  them); the approximate searches answer every query, build included. ``id_recall``: the fraction of those
  queries given the same row as exact search; ``distance_recall``: given a row no farther (in float64, to
  1e-6 relative) than exact search's; ``mean_distance_increase``: relative, over those queries. With
  ``--conversion``, also the embedding the ``nearest-neighbor`` converter searches (both maps, 240 dimensions)
  for the maps ``match`` computes from 10 ground-truth curves.

Methods for the first three: faiss ``IndexFlatL2``, blocked float32 matrix products, and scipy's
``cKDTree`` (built and queried on all cores). Where the tree would take minutes it answers a random subset of
the queries and the time is extrapolated linearly (``extrapolated_from`` says how many it ran): the cost per
query of a tree search does not depend on how many queries there are. Times are medians in seconds.

    python -m benchmarks.bench_neighbors [--repeat 3] [--tree-queries 1000] [--sections spectral,zoomout,rhm,scan]
        [--scan-levels 1,2,3] [--recall-queries 2000] [--hnsw] [--conversion]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np
from scipy.spatial import cKDTree

from benchmarks.bench_scan import subdivided
from benchmarks.common import bench_store, machine, median_ms, shared_data
from curvefm.evaluation import GroundTruth, ground_truth_curves, ground_truth_for
from curvefm.geometry import load_mesh
from curvefm.matching import match
from curvefm.plugins.rhm import RhmParams, prepare_shape
from curvefm.pointwise import fmap_from_pointwise, nearest_neighbors
from curvefm.runtime import limit_blas_threads

# Above this many seconds (estimated from a first subset), the tree answers only a subset of the queries.
TREE_FULL_LIMIT_S = 20.0


def tree_search(data: np.ndarray, queries: np.ndarray, count: int | None) -> np.ndarray:
    rows = queries if count is None else queries[np.random.default_rng(0).choice(len(queries), count, False)]
    return cKDTree(data).query(rows, workers=-1)[1]


def compare(data: np.ndarray, queries: np.ndarray, repeat: int, tree_queries: int) -> dict:
    data, queries = np.ascontiguousarray(data, np.float32), np.ascontiguousarray(queries, np.float32)
    out = {"data": len(data), "queries": len(queries), "dims": data.shape[1]}
    faiss_ids = nearest_neighbors(data, queries, "exact")  # also loads faiss before timing
    out["faiss_s"] = median_ms(lambda: nearest_neighbors(data, queries, "exact"), repeat) / 1e3
    out["blocked_s"] = median_ms(lambda: nearest_neighbors(data, queries, "blocked"), repeat) / 1e3
    out["blocked_agrees_with_faiss"] = float(np.mean(nearest_neighbors(data, queries, "blocked") == faiss_ids))
    count = min(tree_queries, len(queries))
    probe = median_ms(lambda: tree_search(data, queries, count), 1) / 1e3
    if probe * len(queries) / count <= TREE_FULL_LIMIT_S:
        out["cKDTree_s"] = median_ms(lambda: tree_search(data, queries, None), repeat) / 1e3
    else:
        out["cKDTree_s"] = median_ms(lambda: tree_search(data, queries, count), repeat) / 1e3 * len(queries) / count
        out["cKDTree_extrapolated_from"] = count
    return out


def spectral_case(store, source, target, ks: list[int]) -> list[tuple[np.ndarray, np.ndarray]]:
    mesh_M, mesh_N = load_mesh(source), load_mesh(target)
    truth = ground_truth_for(source, target, mesh_M, mesh_N)
    basis_M, basis_N = store.ensure_basis(mesh_M, max(ks)), store.ensure_basis(mesh_N, max(ks))
    p2p_NM = np.zeros(mesh_N.n_vertices, dtype=np.int64)
    p2p_NM[truth.ids_Y] = truth.ids_X
    cases = []
    for k in ks:
        C_MN = fmap_from_pointwise(p2p_NM, basis_M, basis_N, k, k)
        cases.append((basis_M.evecs[:, :k] @ C_MN.T, basis_N.evecs[:, :k]))
    return cases


def rhm_case(store, source, target) -> tuple[np.ndarray, np.ndarray]:
    """RHM's projection N -> M from the 10-curve nearest-neighbour maps, with the final weights:
    data [sqrt(1 - alpha) X_MN, sqrt(beta_max) X_M] (vertices of M), queries [.. X_N, .. X_NM] (of N)."""
    mesh_M, mesh_N = load_mesh(source), load_mesh(target)
    truth = ground_truth_for(source, target, mesh_M, mesh_N)
    result = match(mesh_M, mesh_N, ground_truth_curves(mesh_M, mesh_N, truth, 10), store=store)
    params = RhmParams()
    shape_M = prepare_shape(mesh_M, params)
    shape_N = prepare_shape(mesh_N, params)
    c_r, c_c = np.sqrt(1 - params.alpha), np.sqrt(params.beta_max)
    data = np.hstack([c_r * shape_N.X[result.maps.p2p_MN], c_c * shape_M.X])
    queries = np.hstack([c_r * shape_N.X, c_c * shape_M.X[result.maps.p2p_NM]])
    return data, queries


def recall(data: np.ndarray, queries: np.ndarray, rows: np.ndarray, exact: np.ndarray, found: np.ndarray) -> dict:
    """How ``found`` (for the queries ``rows``) compares with ``exact``, by index and by float64 distance."""
    exact_distance = np.linalg.norm(data[exact] - queries[rows], axis=1)
    found_distance = np.linalg.norm(data[found] - queries[rows], axis=1)
    return {
        "id_recall": float(np.mean(found == exact)),
        "distance_recall": float(np.mean(found_distance <= exact_distance * (1 + 1e-6))),
        "mean_distance_increase": float(found_distance.mean() / exact_distance.mean() - 1),
    }


def timed(fn):
    start = time.perf_counter()
    result = fn()
    return result, round(time.perf_counter() - start, 3)


def hnsw_search(data: np.ndarray, queries: np.ndarray, ef_values: tuple[int, ...]) -> list[dict]:
    """faiss HNSW (32 links a node): ids and seconds (the build included) for each efSearch."""
    import faiss

    index = faiss.IndexHNSWFlat(data.shape[1], 32)
    _, build_s = timed(lambda: index.add(data))
    out = []
    for ef in ef_values:
        index.hnsw.efSearch = ef
        ids, search_s = timed(lambda: index.search(queries, 1)[1][:, 0])
        out.append({"ef_search": ef, "ids": ids, "s": round(build_s + search_s, 2)})
    return out


def exact_against_approximate(data: np.ndarray, queries: np.ndarray, rows: np.ndarray, hnsw: bool) -> dict:
    """Exact search for the queries ``rows`` (time extrapolated to all), approximate search for all."""
    exact, exact_s = timed(lambda: nearest_neighbors(data, queries[rows], "exact"))
    found, approximate_s = timed(lambda: nearest_neighbors(data, queries, "approximate"))
    entry = {"data": len(data), "queries": len(queries), "dims": data.shape[1], "recall_queries": len(rows)}
    entry["exact_s"] = round(exact_s * len(queries) / len(rows), 2)
    entry["approximate_s"] = approximate_s
    entry["speedup"] = round(entry["exact_s"] / approximate_s, 1)
    entry["approximate"] = recall(data, queries, rows, exact, found[rows])
    if hnsw:
        data32, queries32 = (np.ascontiguousarray(a, np.float32) for a in (data, queries))
        runs = hnsw_search(data32, queries32, (64, 256))
        entry["hnsw"] = [
            {"ef_search": run["ef_search"], "s": run["s"]} | recall(data, queries, rows, exact, run["ids"][rows])
            for run in runs
        ]
    return entry


def scan_case(store, level: int, dims: list[int], recall_queries: int, hnsw: bool, conversion: bool) -> list[dict]:
    """Exact against approximate search at one subdivision level, data ``Phi_k C^T`` and queries ``Psi_k``;
    with ``conversion`` also the nearest-neighbor converter's embedding of both maps of a 10-curve match."""
    mesh_M, mesh_N = subdivided("tr_reg_000", level), subdivided("tr_reg_011", level)
    basis_M, basis_N = store.ensure_basis(mesh_M, max(dims)), store.ensure_basis(mesh_N, max(dims))
    count = min(recall_queries, mesh_N.n_vertices)
    rows = np.random.default_rng(0).choice(mesh_N.n_vertices, count, replace=False)
    cases = []
    for k in dims:
        C_MN = fmap_from_pointwise(np.arange(mesh_N.n_vertices), basis_M, basis_N, k, k)
        cases.append(("true map", basis_M.evecs[:, :k] @ C_MN.T, basis_N.evecs[:, :k]))
    if conversion:
        cases.append(("10-curve match, both maps", *conversion_embedding(store, mesh_M, mesh_N)))
    out = []
    for embedding, data, queries in cases:
        entry = {"embedding": embedding} | exact_against_approximate(data, queries, rows, hnsw)
        print(json.dumps(entry), file=sys.stderr, flush=True)
        out.append(entry)
    return out


def conversion_embedding(store, mesh_M, mesh_N) -> tuple[np.ndarray, np.ndarray]:
    """Data ``[Phi C_MN^T, Phi]`` and queries ``[Psi, Psi C_NM^T]`` of the maps ``match`` computes with 10
    ground-truth curves (the subdivided pair shares its vertices, so the identity is the truth)."""
    ids = np.arange(mesh_M.n_vertices)
    curves = ground_truth_curves(mesh_M, mesh_N, GroundTruth(ids, ids, "identity", True), 10)
    result = match(mesh_M, mesh_N, curves, store=store)
    k = result.fmaps.C_MN.shape[0]
    Phi, Psi = result.pair.basis_M.evecs[:, :k], result.pair.basis_N.evecs[:, :k]
    return np.hstack([Phi @ result.fmaps.C_MN.T, Phi]), np.hstack([Psi, Psi @ result.fmaps.C_NM.T])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--tree-queries", type=int, default=1000, help="queries the tree answers when extrapolating")
    parser.add_argument("--sections", default="spectral,zoomout,rhm,scan", help="default %(default)s")
    parser.add_argument("--scan-levels", default="1,2,3", help="subdivision levels of the scan section")
    parser.add_argument("--recall-queries", type=int, default=2000, help="queries exact search answers in scan")
    parser.add_argument("--hnsw", action="store_true", help="also time faiss HNSW in the scan section")
    parser.add_argument("--conversion", action="store_true", help="scan: also a 10-curve match's embedding")
    args = parser.parse_args()
    sections = args.sections.split(",")
    data, store = shared_data(), bench_store()
    report = {"machine": machine(), "load_avg_1min_before": round(os.getloadavg()[0], 2)}
    faust = (data / "faust" / "tr_reg_000.off", data / "faust" / "tr_reg_011.off")
    if "spectral" in sections:
        tosca = (data / "tosca" / "cat0.off", data / "tosca" / "cat1.off")
        report["spectral"] = [
            compare(d, q, args.repeat, args.tree_queries) for d, q in spectral_case(store, *tosca, [50, 120])
        ]
    if "zoomout" in sections:
        cases = spectral_case(store, *faust, [20, 50, 80, 120])
        report["zoomout"] = [compare(d, q, args.repeat, args.tree_queries) for d, q in cases]
    if "rhm" in sections:
        report["rhm"] = [compare(*rhm_case(store, *faust), args.repeat, args.tree_queries)]
    if "scan" in sections:
        levels = [int(level) for level in args.scan_levels.split(",")]
        report["scan"] = [
            entry
            for level in levels
            for entry in scan_case(store, level, [20, 60, 120], args.recall_queries, args.hnsw, args.conversion)
        ]
    report["load_avg_1min_after"] = round(os.getloadavg()[0], 2)
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    limit_blas_threads()
    main()
