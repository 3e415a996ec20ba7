"""The landmark prior at scan resolution: what a live session on big shapes gains from it, and what it costs.

FAUST tr_reg_000 -> tr_reg_011 subdivided ``--level`` times (2: 110,210 vertices; ``trimesh.remesh.subdivide``
keeps the original vertices' ids, so the identity ground truth holds for them), bases as the service computes
them (``laplace-beltrami``, k = 120, multiresolution from 60k vertices; kept in ``--data`` between runs).

* ``accuracy``: with 1, 2 and 5 ground-truth curves (farthest-point endpoints, 2 seeds), the combined energy
  with its landmark prior (the default) against the same energy without it (``prior_weight = 0``, what a live
  session above ``CURVEFM_PRIOR_MAX_VERTICES`` solves); mean straight-line error / sqrt(area) of the original
  6,890 vertices' images (nearest neighbours in the embedding of both maps).
* ``cost``: the prior's one-off work per shape (the eigenfunctions' multiplication operators and the wave kernel
  signatures' part), and then one prior for 10 curves' endpoints (their kernel parts made from those operators),
  each on one core.

Usage: ``python -m experiments.scan_prior [--level 2] [--data DIR]``; prints JSON (2026-11-23's run:
``experiments/scan_prior.json``).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_scan import PAIR, subdivided
from benchmarks.common import machine
from curvefm import registry
from curvefm.evaluation import GroundTruth, ground_truth_curves
from curvefm.fmap import Hints, landmark_prior
from curvefm.pointwise import pointwise_from_both
from curvefm.runtime import limit_blas_threads
from curvefm.spectral import ShapePair
from curvefm.store import Store

COUNTS = (1, 2, 5)
SEEDS = (0, 1)
K = 120


def seconds(fn) -> float:
    start = time.perf_counter()
    fn()
    return round(time.perf_counter() - start, 3)


def accuracy(pair: ShapePair, truth: GroundTruth) -> list[dict]:
    method = registry.get("method", "combined")
    rows = []
    for count in COUNTS:
        errors = {"with prior": [], "without prior": []}
        for seed in SEEDS:
            seed_vertex = int(pair.mesh_M.internal_ids(np.array([seed * 997]))[0])
            hints = Hints.from_curves(ground_truth_curves(pair.mesh_M, pair.mesh_N, truth, count, seed_vertex))
            for name, params in (("with prior", {}), ("without prior", {"prior_weight": 0.0})):
                maps = method.run(pair, hints, method.parse_params(params))
                errors[name].append(euclidean_error(pair, maps, truth))
        rows.append({"curves": count, **{name: round(float(np.mean(e)), 4) for name, e in errors.items()}})
    return rows


def euclidean_error(pair: ShapePair, maps, truth: GroundTruth) -> float:
    """Mean distance from the image of each ground-truth source vertex to its true partner, by sqrt(area) of the
    target (straight-line: geodesic distances from 6,890 vertices of a 110k mesh would cost more than the maps)."""
    images = pointwise_from_both(maps.C_NM, maps.C_MN, pair.basis_N, pair.basis_M, rows=truth.ids_X)
    gaps = np.linalg.norm(pair.mesh_N.vertices[images] - pair.mesh_N.vertices[truth.ids_Y], axis=1)
    return float(gaps.mean() / np.sqrt(pair.mesh_N.area))


def cost(pair: ShapePair, truth: GroundTruth) -> dict:
    bases = (pair.basis_M, pair.basis_N)
    settings = landmark_prior.NO17Settings()
    landmark_prior._EIGEN_PRODUCTS.clear()  # the accuracy runs made them
    landmark_prior._PARTS.clear()
    once = sum(seconds(lambda b=b: landmark_prior._part(b, 0, settings)) for b in bases)
    signatures = sum(seconds(lambda b=b: landmark_prior._part(b, None, settings)) for b in bases)
    landmarks = Hints.from_curves(ground_truth_curves(pair.mesh_M, pair.mesh_N, truth, 10)).landmarks
    return {
        "per_shape_eigen_operators_s": round(once, 3),
        "per_shape_signatures_s": round(signatures, 3),
        "prior_10_curves_s": seconds(lambda: landmark_prior.landmark_maps(bases[0], bases[1], landmarks)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--level", type=int, default=2)
    parser.add_argument("--data", default=os.environ.get("CURVEFM_BENCH_DATA", "/tmp/curvefm-bench-scan-prior"))
    args = parser.parse_args()
    limit_blas_threads(1)
    meshes = [subdivided(name, args.level) for name in PAIR]
    truth = GroundTruth(*(mesh.internal_ids(np.arange(6890)) for mesh in meshes), "identity", True)
    store = Store(Path(args.data))
    basis = registry.get("basis", "laplace-beltrami")
    for mesh in meshes:
        if not store.has_basis(store.put_mesh(mesh), K):
            store.put_basis(
                store.put_mesh(mesh),
                basis.run(mesh, K, basis.parse_params({})),
                basis.name,
                basis.parse_params({}).model_dump(),
            )
    pair = ShapePair(*meshes, *(store.find_basis(mesh.content_hash, K) for mesh in meshes))
    result = {"machine": machine(), "vertices": pair.mesh_M.n_vertices, "accuracy": accuracy(pair, truth)}
    result["cost"] = cost(pair, truth)
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
