"""How the combined energy's landmark prior was set: mean geodesic error (by sqrt(area), source -> target,
nearest-neighbour conversion with the ``both`` embedding, k = 120) with 1, 2, 5, 10 and 20 ground-truth curves
(``curvefm evaluate``'s protocol: 2n farthest points among the vertices with a known partner, consecutive pairs
joined) on FAUST across people and poses, TOSCA wolf and the non-isometric cat -> lion, for the prior's weight
(0: no prior) with the map handed out at the prior's size (50 x 50) and at the basis's (120 x 120), against NO17
and the curve energy given the same curves. Prints one JSON object; experiments/combined_prior.json is its
output."""

import json
import math

from benchmarks.common import machine
from curvefm import registry
from curvefm.evaluation import score
from curvefm.fmap import CombinedMapSolver, CurveMapSolver, FunctionalMaps, Hints, NO17Settings
from curvefm.matching import convert
from curvefm.runtime import limit_blas_threads
from experiments.common import ground_truth_rows

PAIRS = [
    ("faust/tr_reg_000.off", "faust/tr_reg_011.off"),
    ("tosca/wolf0.off", "tosca/wolf2.off"),
    ("nonisometric/pyfm_cat_lion/cat-00.off", "nonisometric/pyfm_cat_lion/lion-00.off"),
]
COUNTS = (1, 2, 5, 10, 20)
PRIOR_WEIGHTS = (0, 10, 30, 100)
PRIOR_SIZE = NO17Settings().k


def errors_for(pair, truth, curves, converter) -> dict:
    def error(maps):
        return round(score(convert(pair, maps, *converter), truth)["source_to_target"]["mean_area"], 4)

    bases = (pair.mesh_M.vertices, pair.basis_M, pair.mesh_N.vertices, pair.basis_N)
    terms = [(pm, pn, 1.0) for pm, pn in curves]
    no17, no17_params = registry.load("method", "no17", None)
    row = {"no17": error(no17.run(pair, Hints.from_curves(curves), no17_params))}
    with CurveMapSolver(*bases) as solver:
        solver.add_curves(terms)
        row["curves"] = error(FunctionalMaps(solver.C_MN, solver.C_NM))
    for weight in PRIOR_WEIGHTS:
        whole = {"full_size_curves": 1, "non_isometric_spectra": math.inf}  # 120 x 120 as solved
        with CombinedMapSolver(*bases, prior_weight=weight, **whole) as solver:
            solver.add_curves(terms)
            C_MN, C_NM = solver.C_MN, solver.C_NM
        row[f"prior {weight}, 120"] = error(FunctionalMaps(C_MN, C_NM))
        row[f"prior {weight}, {PRIOR_SIZE}"] = error(
            FunctionalMaps(C_MN[:PRIOR_SIZE, :PRIOR_SIZE], C_NM[:PRIOR_SIZE, :PRIOR_SIZE])
        )
    return row


def main():
    limit_blas_threads(1)
    converter = registry.load("converter", "nearest-neighbor", {"embedding": "both"})
    rows = ground_truth_rows(PAIRS, COUNTS, lambda pair, truth, curves: errors_for(pair, truth, curves, converter))
    print(
        json.dumps(
            {
                "benchmark": "combined_prior",
                "machine": machine(),
                "k": 120,
                "error": "mean geodesic error / sqrt(area), source -> target",
                "rows": rows,
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
