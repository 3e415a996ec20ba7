"""Exact nearest neighbours in the embeddings the refining converters search (prints JSON).

* ``spectral``: TOSCA cat0 -> cat1 (27,894 vertices each): data ``Phi_k C^T``, queries ``Psi_k``, with C the
  functional map of the true correspondence, k = 50 and 120 (the design budget: 30k x 30k in 120 dimensions).
* ``zoomout``: FAUST tr_reg_000 -> 011 (6,890 vertices) at the sizes ZoomOut steps through (20 to 120).
* ``rhm``: FAUST, the 16-dimensional stacked geodesic-MDS embeddings RHM projects in (from 10-curve maps).

Methods: faiss ``IndexFlatL2``, blocked float32 matrix products (:mod:`curvefm.pointwise.neighbors`), and scipy's
``cKDTree`` (built and queried on all cores). Where the tree would take minutes it answers a random subset of
the queries and the time is extrapolated linearly (``extrapolated_from`` says how many it ran): the cost per
query of a tree search does not depend on how many queries there are. Times are medians in seconds.

    python benchmarks/bench_neighbors.py [--repeat 3] [--tree-queries 1000]
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from common import bench_store, machine, median_ms, shared_data
from scipy.spatial import cKDTree

from curvefm.evaluation import ground_truth_curves, ground_truth_for
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
    faiss_ids = nearest_neighbors(data, queries, "faiss")  # also loads faiss before timing
    out["faiss_s"] = median_ms(lambda: nearest_neighbors(data, queries, "faiss"), repeat) / 1e3
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--tree-queries", type=int, default=1000, help="queries the tree answers when extrapolating")
    args = parser.parse_args()
    data, store = shared_data(), bench_store()
    report = {"machine": machine(), "spectral": [], "zoomout": [], "rhm": []}
    tosca = (data / "tosca" / "cat0.off", data / "tosca" / "cat1.off")
    for d, q in spectral_case(store, *tosca, [50, 120]):
        report["spectral"].append(compare(d, q, args.repeat, args.tree_queries))
    faust = (data / "faust" / "tr_reg_000.off", data / "faust" / "tr_reg_011.off")
    for d, q in spectral_case(store, *faust, [20, 50, 80, 120]):
        report["zoomout"].append(compare(d, q, args.repeat, args.tree_queries))
    report["rhm"].append(compare(*rhm_case(store, *faust), args.repeat, args.tree_queries))
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    limit_blas_threads()
    main()
