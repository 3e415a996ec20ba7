"""The landmark prior at scan resolution: what a live session on big shapes gains from it, and what it costs.

FAUST tr_reg_000 -> tr_reg_011 subdivided ``--level`` times (2: 110,210 vertices; ``trimesh.remesh.subdivide``
keeps the original vertices' ids, so the identity ground truth holds for them), bases as the service computes
them (``laplace-beltrami``, k = 120, multiresolution from 60k vertices; kept in ``--data`` between runs).

* ``accuracy``: with 1, 2, 5 and 10 ground-truth curves (farthest-point endpoints, 3 seeds), the combined energy
  with its landmark prior (the default) against the same energy without it (``prior_weight = 0``, what a live
  session above ``CURVEFM_PRIOR_MAX_VERTICES`` solves); mean geodesic error / sqrt(area) on the original 6,890
  vertices, nearest-neighbour conversion.
* ``cost``: the prior's one-off work per shape (the eigenfunctions' multiplication operators and the wave kernel
  signatures' part), and then one prior for 10 curves' endpoints (their kernel parts made from those operators),
  each on one core.

Usage: ``python benchmarks/bench_scan_prior.py [--level 2] [--data DIR]``; prints JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from bench_scan import PAIR, subdivided
from common import machine

from curvefm.evaluation import GroundTruth, ground_truth_curves, score
from curvefm.fmap import Hints, landmark_prior
from curvefm.matching import match
from curvefm.runtime import limit_blas_threads
from curvefm.store import Store

COUNTS = (1, 2, 5, 10)
SEEDS = (0, 1, 2)


def seconds(fn) -> float:
    start = time.perf_counter()
    fn()
    return round(time.perf_counter() - start, 3)


def accuracy(meshes, truth, store: Store) -> list[dict]:
    rows = []
    for count in COUNTS:
        errors = {"with prior": [], "without prior": []}
        for seed in SEEDS:
            seed_vertex = meshes[0].internal_ids(np.array([seed * 997]))[0]
            curves = ground_truth_curves(meshes[0], meshes[1], truth, count, seed_vertex=int(seed_vertex))
            for name, params in (("with prior", {}), ("without prior", {"prior_weight": 0.0})):
                result = match(meshes[0], meshes[1], curves, store=store, method_params=params)
                errors[name].append(score(result, truth)["source_to_target"]["mean_area"])
        rows.append({"curves": count, **{name: round(float(np.mean(e)), 4) for name, e in errors.items()}})
    return rows


def cost(meshes, truth, store: Store) -> dict:
    bases = [store.find_basis(store.put_mesh(mesh), 120) for mesh in meshes]  # stored by the accuracy runs
    settings = landmark_prior.NO17Settings()
    landmark_prior._EIGEN_PRODUCTS.clear()  # the accuracy runs made them
    landmark_prior._PARTS.clear()
    once = sum(seconds(lambda b=b: landmark_prior._part(b, 0, settings)) for b in bases)
    signatures = sum(seconds(lambda b=b: landmark_prior._part(b, None, settings)) for b in bases)
    landmarks = Hints.from_curves(ground_truth_curves(meshes[0], meshes[1], truth, 10)).landmarks
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
    result = {"machine": machine(), "vertices": meshes[0].n_vertices, "accuracy": accuracy(meshes, truth, store)}
    result["cost"] = cost(meshes, truth, store)
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
