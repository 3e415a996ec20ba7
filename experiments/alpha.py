"""How the default commutativity weight alpha was chosen: mean geodesic error (by sqrt(area), source ->
target, nearest-neighbour conversion) for 10 ground-truth curves over a sweep of alpha, on FAUST pairs
across people and poses and on the non-isometric cat -> lion. Prints one JSON object."""

import json

from benchmarks.common import bench_store, machine, shared_data
from curvefm.evaluation import ground_truth_curves, ground_truth_for, score
from curvefm.geometry import load_mesh
from curvefm.matching import match
from curvefm.runtime import limit_blas_threads

PAIRS = [
    ("faust/tr_reg_000.off", "faust/tr_reg_011.off"),
    ("faust/tr_reg_020.off", "faust/tr_reg_031.off"),
    ("faust/tr_reg_040.off", "faust/tr_reg_051.off"),
    ("nonisometric/pyfm_cat_lion/cat-00.off", "nonisometric/pyfm_cat_lion/lion-00.off"),
]
ALPHAS = [1, 10, 30, 100, 300, 1000, 10000]


def main():
    data, store = shared_data(), bench_store()
    table = []
    for source, target in PAIRS:
        M, N = load_mesh(data / source), load_mesh(data / target)
        truth = ground_truth_for(data / source, data / target, M, N)
        curves = ground_truth_curves(M, N, truth, 10)
        row = {"pair": f"{source} -> {target}", "errors": {}}
        for alpha in ALPHAS:
            result = match(M, N, curves, alpha=alpha, store=store, method="curves")
            row["errors"][str(alpha)] = round(score(result, truth)["source_to_target"]["mean_area"], 4)
        table.append(row)
    mean = {str(a): round(sum(r["errors"][str(a)] for r in table) / len(table), 4) for a in ALPHAS}
    print(
        json.dumps(
            {
                "benchmark": "alpha_sweep",
                "machine": machine(),
                "curves": 10,
                "k": 120,
                "error": "mean geodesic error / sqrt(area), source -> target",
                "pairs": table,
                "mean_over_pairs": mean,
                "best": min(mean, key=mean.get),
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    limit_blas_threads()
    main()
