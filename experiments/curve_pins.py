"""How right are the curve pins the refiners hold? (:class:`curvefm.pointwise.CurvePins`)

On pairs of the reproduce suite with traced curves (``CurvePool``, as ``curvefm reproduce`` draws them), for every
vertex of a target curve with a ground-truth partner: the geodesic distance on the source, by sqrt(area), from that
partner to the source vertex the pins send it to (the source curve's vertex at the same normalised arc length, the
ends onto the ends), and to the vertex the default method's map sends it to (the ``nearest-neighbor`` converter's
``p2p_NM``), which the pins overrule. Prints one JSON object: per pair, count and seed the two means and the number
of curve vertices measured.

    nice python -m experiments.curve_pins [--counts 2 10] [--seeds 3] [--pairs cat-lion tr_reg_000->tr_reg_011]

Result (2026-11-24, experiments/curve_pins.json): traced curves do not follow each other exactly, so the pins are
off by more than the map they overrule, in 17 of the 18 runs (FAUST 000 -> 011 with 10 curves: pins 0.029-0.043,
the map 0.013-0.022; cat -> lion 0.025-0.040 against 0.024-0.026; docs/experiments/curve-pins.md). Since issue 35
the refiners pin only the curves' ends (experiments/pin_rule.py); this measures the arc-length partners they once
pinned every curve vertex to.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from benchmarks.common import machine, shared_data
from curvefm import registry
from curvefm.evaluation.reproduce.datasets import FULL_PAIRS
from curvefm.evaluation.reproduce.scoring import LoadedPair
from curvefm.fmap import DEFAULT_K, Hints
from curvefm.geometry import geodesic_distances
from curvefm.pointwise import CurvePins
from curvefm.runtime import limit_blas_threads
from curvefm.store import Store


def run(loaded: LoadedPair, count: int, seed: int) -> dict:
    shapes, truth = loaded.shapes, loaded.truth
    curves = loaded.pool.curves(count, seed, False)
    method, params = registry.load("method", "combined", {})
    converter, defaults = registry.load("converter", "nearest-neighbor", None)
    p2p_NM = converter.run(shapes, method.run(shapes, Hints.from_curves(curves), params), defaults).p2p_NM
    pins = CurvePins.from_curves(shapes.mesh_M, shapes.mesh_N, curves, hard_interiors=True)  # the rule it judged
    pinned_NM = pins.pin_NM(p2p_NM)
    true_partner = dict(zip(truth.ids_Y.tolist(), truth.ids_X.tolist(), strict=True))
    on_curves = np.unique(np.concatenate([path_N for _, path_N in curves]))
    measured = np.array([y for y in on_curves if y in true_partner], dtype=np.int64)
    partners = np.array([true_partner[y] for y in measured], dtype=np.int64)
    distances = geodesic_distances(shapes.mesh_M, partners)  # rows: the true partners
    rows = np.arange(len(measured))
    scale = np.sqrt(shapes.mesh_M.area)
    return {
        "dataset": loaded.pair.dataset,
        "pair": loaded.pair.name,
        "count": count,
        "seed": seed,
        "curve_vertices": len(measured),
        "pins": round(float(distances[rows, pinned_NM[measured]].mean() / scale), 5),
        "map": round(float(distances[rows, p2p_NM[measured]].mean() / scale), 5),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[2, 10])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument(
        "--pairs",
        nargs="+",
        default=["tr_reg_000->tr_reg_011", "cat-lion"],
        help="datasets or pair names of the reproduce suite",
    )
    args = parser.parse_args()
    limit_blas_threads()
    data, store, rows = shared_data(), Store(), []
    for pair in FULL_PAIRS:
        if pair.dataset not in args.pairs and pair.name not in args.pairs:
            continue
        loaded = LoadedPair.load(data, pair, DEFAULT_K, store)
        if not loaded.truth.dense:
            continue  # sparse landmarks: the curves' vertices have no partners to measure
        rows.extend(run(loaded, count, seed) for count in args.counts for seed in range(args.seeds))
    print(json.dumps({"benchmark": "curve_pins", "machine": machine(), "k": DEFAULT_K, "rows": rows}))


if __name__ == "__main__":
    main()
