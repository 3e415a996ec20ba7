"""How the combined energy's default weights were chosen: mean geodesic error (by sqrt(area), source -> target,
nearest-neighbour conversion with the ``both`` embedding, k = 120) with 2 and 10 ground-truth curves (2n farthest
points among the vertices with a known partner, consecutive pairs joined: ``curvefm evaluate``'s protocol) over a
grid of alpha, the signature weight and the kernel weight (without the landmark prior, which came later), on
FAUST across people and poses, TOSCA wolf and the non-isometric cat -> lion. Weight 0 for both descriptor terms
is the pure curve energy. Prints one JSON object."""

import itertools
import json

import numpy as np

from benchmarks.common import machine
from curvefm import registry
from curvefm.evaluation import score
from curvefm.fmap import CombinedMapSolver, FunctionalMaps
from curvefm.matching import convert
from curvefm.runtime import limit_blas_threads
from experiments.common import ground_truth_rows

PAIRS = [
    ("faust/tr_reg_000.off", "faust/tr_reg_011.off"),
    ("tosca/wolf0.off", "tosca/wolf2.off"),
    ("nonisometric/pyfm_cat_lion/cat-00.off", "nonisometric/pyfm_cat_lion/lion-00.off"),
]
COUNTS = (2, 10)
ALPHAS = (30, 100, 300)
WEIGHTS = ((0, 0), (10, 10), (100, 100), (1000, 1000), (10, 100), (100, 10), (100, 1000), (1000, 100))
"""(signature weight, kernel weight); (0, 0) is the pure curve energy"""


def pair_errors(pair, truth, curves, converter):
    """{config key: error} for every weight combination on one pair and curve set."""
    errors = {}
    for alpha, (w_d, w_k) in itertools.product(ALPHAS, WEIGHTS):
        solver = CombinedMapSolver(
            pair.mesh_M.vertices,
            pair.basis_M,
            pair.mesh_N.vertices,
            pair.basis_N,
            alpha=alpha,
            descriptor_weight=w_d,
            kernel_weight=w_k,
            prior_weight=0,
        )
        solver.add_curves([(pm, pn, 1.0) for pm, pn in curves])
        result = convert(pair, FunctionalMaps(solver.C_MN, solver.C_NM), *converter)
        errors[f"{alpha}/{w_d}/{w_k}"] = round(score(result, truth)["source_to_target"]["mean_area"], 4)
        solver.close()
    return errors


def main():
    converter = registry.load("converter", "nearest-neighbor", {"embedding": "both"})  # the default until 2026-11-23
    rows = ground_truth_rows(PAIRS, COUNTS, lambda pair, truth, curves: pair_errors(pair, truth, curves, converter))
    keys = list(rows[0]["errors"])
    mean = {key: round(float(np.mean([r["errors"][key] for r in rows])), 4) for key in keys}
    worst_ratio = {
        key: round(max(r["errors"][key] / r["errors"][f"{a}/0/0"] for r in rows for a in [key.split("/")[0]]), 3)
        for key in keys
    }
    best = min(mean, key=mean.get)
    print(
        json.dumps(
            {
                "benchmark": "combined_weights",
                "machine": machine(),
                "k": 120,
                "key": "alpha/descriptor_weight/kernel_weight",
                "error": "mean geodesic error / sqrt(area), source -> target",
                "rows": rows,
                "mean_over_rows": mean,
                "worst_ratio_to_curves_same_alpha": worst_ratio,
                "best": best,
                "best_rows": {f"{r['pair']} ({r['curves']})": r["errors"][best] for r in rows},
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    limit_blas_threads()
    main()
