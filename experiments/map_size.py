"""Which size should the combined map be handed out at, with many curves? Mean error by geodesic diameter (the
reproduce report's figure) of the combined energy solved at k = 120 and handed out at s x s, for several prior
weights, on ``curvefm reproduce``'s full suite (its pairs, ``CurvePool`` traced curves, seeds and scorer; counts a
pair's pool cannot draw are skipped, as the report skips them). Prints one JSON object;
experiments/map_size.json is its output (``--counts 10 20 --weights 3 10 30`` and ``--counts 30 40 --weights 30``,
2026-11-23; deterministic, so the busy machine does not matter).

Result, not adopted: no size serves isometric and non-isometric pairs together. From 20 curves on cat -> lion is
best at 50-70 (20 curves: 0.0202 / 0.0203, 120: 0.0218, NO17 0.0204), FAUST, TOSCA and TOSCA across classes at
120 (TOSCA 20: 0.0114, at 70 0.0135). Size 70 at 20 curves would beat every baseline on all five datasets, at the
price of FAUST (0.0100 -> 0.0105) and TOSCA (0.0114 -> 0.0135) with 20 curves, so the default stays 120 there.

    nice python -m experiments.map_size [--counts 10 20] [--weights 3 10 30] [--sizes 50 70 90 120]
"""

import argparse
import json
from collections import defaultdict

import numpy as np

from benchmarks.common import machine, shared_data
from curvefm import registry
from curvefm.evaluation.reproduce.datasets import FULL_PAIRS
from curvefm.evaluation.reproduce.scoring import LoadedPair
from curvefm.fmap import DEFAULT_K, Hints
from curvefm.progress import no_progress
from curvefm.runtime import limit_blas_threads
from curvefm.store import Store

SEEDS = 3


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[10, 20])
    parser.add_argument("--weights", type=float, nargs="+", default=[3.0, 10.0, 30.0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[50, 70, 90, 120])
    args = parser.parse_args()
    limit_blas_threads()
    data, store = shared_data(), Store()
    errors = defaultdict(list)
    for pair in FULL_PAIRS:
        loaded = LoadedPair.load(data, pair, DEFAULT_K, store)
        for count in (c for c in args.counts if c <= loaded.pool.max_curves):
            for seed in range(SEEDS):
                curves = loaded.pool.curves(count, seed, False)
                hints = Hints.from_curves(curves)
                for weight in args.weights:
                    params = {"prior_weight": weight, "full_size_curves": 1}  # solved and handed out at 120 x 120
                    plugin, params = registry.load("method", "combined", params)
                    maps = plugin.run(loaded.shapes, hints, params, no_progress)
                    for size in args.sizes:
                        C_NM = maps.C_NM[:size, :size]
                        error = loaded.score(C_NM, seed, curves).mean
                        errors[(pair.dataset, count, weight, size)].append(error)
    rows = [
        {"dataset": d, "curves": c, "prior_weight": w, "size": s, "runs": len(e), "mean": round(float(np.mean(e)), 5)}
        for (d, c, w, s), e in errors.items()
    ]
    print(json.dumps({"benchmark": "map_size", "machine": machine(), "k": DEFAULT_K, "seeds": SEEDS, "rows": rows}))


if __name__ == "__main__":
    main()
