"""Does refinement ever end worse than its start? ``zoomout`` and ``rhm`` (defaults) through
:func:`curvefm.matching.convert`, whose guard keeps the nearest-neighbour maps when an intrinsic figure got worse,
on every pair of the reproduce suite (``FULL_PAIRS``: FAUST, FAUST-5k, TOSCA within and across classes,
cat -> lion), with 2 and 10 traced curves drawn as ``curvefm reproduce`` draws them (``CurvePool``, seed 0).

Each row starts from the default method's (``combined``) functional maps at k = 120 and records the mean geodesic
error / sqrt(area) of the start (the ``nearest-neighbor`` converter, defaults: the maps the guard compares with), of
each refiner's returned map (the refined one, ZoomOut stopped at a smaller size, or the start), and of the map the
refiner produced before the guard chose (``refined``), source -> target / target -> source on the ground truth
(dense, or across TOSCA classes the shared landmarks the curves do not end at, as ``curvefm reproduce`` scores
them; never at a curve's end, which the refiners pin), which map was kept and why, the intrinsic figures, and
the converter's seconds (guard included). ``--held-out`` runs the pairs held out of the suite instead. A
*regression* is a row where a refiner's returned map is worse than its start by more than 1% (relative, on the mean
of both directions); a *missed gain* is one where the guard returned the start or an earlier stage although the
whole refinement's map was better than that by more than 1%. Prints one JSON object (``--out``
also writes it); experiments/refinement_guard.json is its output, experiments/refinement_guard_held_out.json that of
``--held-out``.

    nice python -m experiments.refinement_guard [--counts 2 10] [--seeds 0] [--pairs faust tosca-cross] [--held-out]
        [--out experiments/refinement_guard.json] [--maps-dir DIR]

``--maps-dir`` also saves each row's start and refined maps (``.npz``), so a change of the guard can be
re-checked without running the refiners again. Bases come from the store (``CURVEFM_DATA``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

from benchmarks.common import machine, shared_data
from curvefm import registry
from curvefm.evaluation import score
from curvefm.evaluation.protocol import scored_truth
from curvefm.evaluation.reproduce.datasets import FULL_PAIRS
from curvefm.evaluation.reproduce.scoring import LoadedPair
from curvefm.fmap import DEFAULT_K, Hints
from curvefm.matching import MatchResult, convert
from curvefm.runtime import limit_blas_threads
from curvefm.store import Store
from experiments.common import HELD_OUT_PAIRS, truth_away_from_ends

REFINERS = ("zoomout", "rhm")
MAPS = ("start", *REFINERS)
REGRESSION = 0.01  # relative


def errors(result: MatchResult, truth) -> dict:
    """Mean geodesic error / sqrt(area) both ways and their mean."""
    both = {d: round(e["mean_area"], 5) for d, e in score(result, truth).items()}
    return both | {"mean": round(0.5 * (both["source_to_target"] + both["target_to_source"]), 5)}


def recording(plugin):
    """The converter ``plugin`` keeping the maps of its whole refinement (what ``run`` returns, the first of its
    ``stages``) in ``box["maps"]``, before the guard chose."""
    box = {}

    def run(*args, **kwargs):
        box["maps"] = plugin.run(*args, **kwargs)
        return box["maps"]

    def stages(*args, **kwargs):
        for number, (label, maps) in enumerate(plugin.stages(*args, **kwargs)):
            if number == 0:
                box["maps"] = maps
            yield label, maps

    return dataclasses.replace(plugin, run=run, stages=stages if plugin.stages else None), box


def refine(loaded: LoadedPair, fmaps, paths, truth, name: str, maps_out: dict) -> dict:
    plugin, params = registry.load("converter", name, None)
    wrapped, box = recording(plugin)
    start = time.perf_counter()
    result = convert(loaded.shapes, fmaps, wrapped, params, paths=paths)
    seconds = time.perf_counter() - start
    refined = dataclasses.replace(result, maps=box["maps"])
    maps_out[f"{name}_MN"], maps_out[f"{name}_NM"] = box["maps"].p2p_MN, box["maps"].p2p_NM
    return {
        "returned": errors(result, truth),
        "refined": errors(refined, truth),
        "kept": result.kept,
        "reason": result.reason,
        "quality": result.quality,
        "seconds": round(seconds, 1),
    }


def run_row(loaded: LoadedPair, count: int, seed: int, maps_dir: Path | None) -> dict:
    paths = loaded.pool.curves(count, seed, exact=False)
    truth = truth_away_from_ends(scored_truth(loaded.truth, seed), paths)
    method, method_params = registry.load("method", "combined", None)
    start = time.perf_counter()
    fmaps = method.run(loaded.shapes, Hints.from_curves(paths), method_params, lambda *_: None)
    row = {
        "pair": loaded.pair.name,
        "dataset": loaded.pair.dataset,
        "count": count,
        "seed": seed,
        "vertices": [loaded.shapes.mesh_M.n_vertices, loaded.shapes.mesh_N.n_vertices],
        "truth": f"{truth.kind}, {len(truth)} rows",
        "solve_s": round(time.perf_counter() - start, 1),
    }
    nn, nn_params = registry.load("converter", "nearest-neighbor", None)
    start_result = convert(loaded.shapes, fmaps, nn, nn_params, paths=paths)
    row["start"] = errors(start_result, truth)
    maps = {"start_MN": start_result.maps.p2p_MN, "start_NM": start_result.maps.p2p_NM}
    for name in REFINERS:
        row[name] = refine(loaded, fmaps, paths, truth, name, maps)
        print(
            f"{loaded.pair.name} {count} curves: {name} {row[name]['returned']['mean']} "
            f"(start {row['start']['mean']}, refined {row[name]['refined']['mean']}, kept {row[name]['kept']}, "
            f"{row[name]['seconds']} s)",
            file=sys.stderr,
            flush=True,
        )
    if maps_dir is not None:
        maps_dir.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(maps_dir / f"{loaded.pair.dataset}_{loaded.pair.name}_{count}_{seed}.npz", **maps)
    return row


def mean_error(row: dict, key: str) -> float:
    """The row's error (mean of both directions) of the start or of a refiner's returned map."""
    return row[key]["mean"] if key == "start" else row[key]["returned"]["mean"]


def summarise(rows: list[dict]) -> dict:
    regressions, missed = [], []
    for row in rows:
        before = row["start"]["mean"]
        for name in REFINERS:
            entry = {
                "pair": row["pair"],
                "count": row["count"],
                "seed": row["seed"],
                "refiner": name,
                "start": before,
                "returned": row[name]["returned"]["mean"],
                "refined": row[name]["refined"]["mean"],
                "reason": row[name]["reason"],
            }
            if mean_error(row, name) > (1 + REGRESSION) * before:
                regressions.append(entry)
            if row[name]["kept"] != "refined" and entry["refined"] < (1 - REGRESSION) * entry["returned"]:
                missed.append(entry)
    return {
        "rows": len(rows),
        "regressions": len(regressions),
        "regression_list": regressions,
        "missed_gains": len(missed),
        "missed_gain_list": missed,
        "kept": {name: dict(Counter(row[name]["kept"] for row in rows)) for name in REFINERS},
        "mean_error": {key: round(float(np.mean([mean_error(row, key) for row in rows])), 5) for key in MAPS},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[2, 10], help="curve counts (default 2 10)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0], help="curve draws (default 0)")
    parser.add_argument("--pairs", nargs="+", default=None, help="datasets or pair names (default: all 12 pairs)")
    parser.add_argument("--held-out", action="store_true", help="the pairs held out of the suite (experiments.common)")
    parser.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    parser.add_argument("--maps-dir", type=Path, default=None, help="save each row's start and refined maps here")
    args = parser.parse_args()
    data, store = shared_data(), Store()
    pool = HELD_OUT_PAIRS if args.held_out else FULL_PAIRS
    pairs = [p for p in pool if args.pairs is None or p.dataset in args.pairs or p.name in args.pairs]
    report = {
        "benchmark": "refinement_guard",
        "machine": machine(),
        "k": DEFAULT_K,
        "method": "combined",
        "curves": "traced, CurvePool (as curvefm reproduce)",
        "counts": args.counts,
        "seeds": args.seeds,
        "error": "mean geodesic error / sqrt(area): source_to_target, target_to_source, mean of both",
        "regression": f"returned map's mean worse than the start's by more than {REGRESSION:.0%}",
    }
    report["machine"]["load_avg_1min_before"] = round(os.getloadavg()[0], 2)
    rows, begin = [], time.perf_counter()
    for pair in pairs:
        loaded = LoadedPair.load(data, pair, DEFAULT_K, store)
        for count in args.counts:
            for seed in args.seeds:
                rows.append(run_row(loaded, count, seed, args.maps_dir))
    report["machine"]["load_avg_1min_after"] = round(os.getloadavg()[0], 2)
    report["seconds"] = round(time.perf_counter() - begin)
    report["summary"] = summarise(rows)
    report["rows"] = rows
    text = json.dumps(report, indent=1)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    limit_blas_threads(1)
    main()
