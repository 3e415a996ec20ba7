"""Which commutativity and kernel weights should the combined map be solved with once it is handed out whole
(from ``FULL_SIZE_CURVES`` = 20 curves on)?

The defaults ``alpha`` and ``kernel_weight`` were swept (experiments/combined_weights.py) where the map is handed out at
the prior's size, 50 x 50. From 20 curves on the whole k = 120 map is handed out, and its higher frequencies are
determined by the curves. On ``curvefm reproduce``'s suite (its pairs with 20 curves, ``CurvePool`` traced curves,
3 seeds and scorer: mean error by geodesic diameter of ``C_NM`` converted by nearest neighbours; TOSCA across classes
at the landmarks the curves do not end at), the ``combined`` method with every rule applied (strongly non-isometric
pairs fall back to the curve energy, which these weights do not touch) for each ``full_size_alpha`` x
``full_size_kernel_weight``. ``--pairs held-out`` runs twelve pairs the suite does not hold, to check the choice.
Prints one JSON object: per dataset the mean for each setting, NO17 beside them, and every run. Deterministic.

    nice python -m experiments.full_size_weights [--alphas 10 30 100] [--kernel-weights 100 300 1000]

Result (2026-11-24; experiments/full_size_weights.json and full_size_weights_held_out.json), adopted as
``FULL_SIZE_ALPHA`` = 30 and ``FULL_SIZE_KERNEL_WEIGHT`` = 300: docs/experiments/full-size-weights.md.
"""

import argparse
import itertools
import json

import numpy as np

from benchmarks.common import machine, shared_data
from curvefm import registry
from curvefm.evaluation.reproduce.scoring import LoadedPair
from curvefm.fmap import DEFAULT_K, FULL_SIZE_CURVES, Hints
from curvefm.progress import no_progress
from curvefm.runtime import limit_blas_threads
from curvefm.store import Store
from experiments.common import add_pair_arguments, chosen_pairs

SEEDS = 3


def run(loaded: LoadedPair, seed: int, settings: dict[str, dict]) -> dict:
    curves = loaded.pool.curves(FULL_SIZE_CURVES, seed, False)
    hints = Hints.from_curves(curves)
    errors = {}
    for name, params in settings.items():
        plugin, checked = registry.load("method", "no17" if name == "no17" else "combined", params)
        maps = plugin.run(loaded.shapes, hints, checked, no_progress)
        errors[name] = round(loaded.score(maps.C_NM, seed, curves).mean, 6)
    return {"dataset": loaded.pair.dataset, "pair": loaded.pair.name, "seed": seed, "errors": errors}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--alphas", type=float, nargs="+", default=[10.0, 30.0, 100.0])
    parser.add_argument("--kernel-weights", type=float, nargs="+", default=[100.0, 300.0, 1000.0])
    add_pair_arguments(parser)
    args = parser.parse_args()
    limit_blas_threads()
    settings = {"no17": {}} | {
        f"{alpha:g}/{weight:g}": {"full_size_alpha": alpha, "full_size_kernel_weight": weight}
        for alpha, weight in itertools.product(args.alphas, args.kernel_weights)
    }
    data, store, rows = shared_data(), Store(), []
    for pair in chosen_pairs(args):
        loaded = LoadedPair.load(data, pair, DEFAULT_K, store)
        if loaded.pool.max_curves >= FULL_SIZE_CURVES:
            rows.extend(run(loaded, seed, settings) for seed in range(SEEDS))
    datasets = {}
    for row in rows:
        datasets.setdefault(row["dataset"], []).append(row["errors"])
    means = {
        name: {s: round(float(np.mean([r[s] for r in runs])), 5) for s in settings} for name, runs in datasets.items()
    }
    print(
        json.dumps(
            {
                "benchmark": "full_size_weights",
                "machine": machine(),
                "k": DEFAULT_K,
                "curves": FULL_SIZE_CURVES,
                "pairs": args.pairs,
                "key": "full_size_alpha/full_size_kernel_weight",
                "means": means,
                "rows": rows,
            }
        )
    )


if __name__ == "__main__":
    main()
