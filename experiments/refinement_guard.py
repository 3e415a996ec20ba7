"""Does refinement ever end worse than its start? ``zoomout`` and ``rhm`` (defaults) through
:func:`curvefm.matching.convert`, whose guard keeps the nearest-neighbour maps when an intrinsic figure got worse,
on every pair of the reproduce suite (``FULL_PAIRS``: FAUST, FAUST-5k, TOSCA within and across classes,
cat -> lion), with 2 and 10 traced curves drawn as ``curvefm reproduce`` draws them (``CurvePool``, seed 0; or with
``--curves farthest`` 2n farthest points, consecutive pairs joined, issue 35's protocol), their endpoints chosen on
the source and, in a row of their own, on the target (``--endpoints-on``).

Each row starts from the default method's (``combined``) functional maps at k = 120 and records the mean geodesic
error / sqrt(area) of the start (the ``nearest-neighbor`` converter, defaults: the maps the guard compares with), of
each refiner's returned map (the refined one, ZoomOut stopped at a smaller size, or the start), and of the map the
refiner produced before the guard chose (``refined``), source -> target / target -> source on the ground truth
(dense, or across TOSCA classes the shared landmarks the curves were not drawn from), never at a curve's end, which
the refiners pin (:func:`curvefm.evaluation.truth_to_score`), which map was kept and why, the intrinsic figures, and
the converter's seconds (guard included). ``--pairs held-out`` runs the pairs held out of the suite instead. A
*regression* is a row where a refiner's returned map is worse than its start by more than 1% (relative, on the mean
of both directions); an *accepted worsening* is one where the guard returned the refined (or stopped) map although it
is worse than the start by more than 1% on the mean or in either direction; a *missed gain* is one where the guard
returned the start or an earlier stage although the whole refinement's map was better than that by more than 1%.
Prints one JSON object (``--out`` also writes it, after every row); experiments/refinement_guard.json is its output,
experiments/refinement_guard_held_out.json that of ``--pairs held-out`` (with both sides since 2026-11-28:
experiments/refinement_guard_both_directions_held_out.json), experiments/accuracy_both_directions.json
that of ``--datasets faust cat-lion --names tr_reg_000->tr_reg_011 cat-00->lion-00 --curves farthest`` (the tables
of docs/accuracy.md).

    nice python -m experiments.refinement_guard [--pairs suite|held-out] [--datasets faust tosca-cross]
        [--names PAIR ...] [--counts 2 10] [--seeds 0] [--endpoints-on source target] [--curves pool|farthest]
        [--refiners zoomout rhm]
        [--out experiments/refinement_guard.json] [--maps-dir DIR]

``--maps-dir`` also saves each row's start and refined maps (``.npz``), so a change of the guard can be
re-checked without running the refiners again. Bases come from ``CURVEFM_BENCH_DATA`` (``benchmarks.common``).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import os
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

from benchmarks.common import machine
from curvefm import registry
from curvefm.evaluation import ENDPOINT_SIDES, CurvePool, ground_truth_curves, score, truth_to_score
from curvefm.fmap import DEFAULT_K, Hints
from curvefm.matching import MatchResult, convert
from curvefm.runtime import limit_blas_threads
from curvefm.spectral import ShapePair
from experiments.common import add_pair_arguments, chosen_pairs, ground_truth_pair

REFINERS = ("zoomout", "rhm")
MAPS = ("start", *REFINERS)
REGRESSION = 0.01  # relative
DIRECTIONS = ("source_to_target", "target_to_source")


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


def refine(shapes: ShapePair, fmaps, paths, truth, name: str, maps_out: dict) -> dict:
    plugin, params = registry.load("converter", name, None)
    wrapped, box = recording(plugin)
    start = time.perf_counter()
    result = convert(shapes, fmaps, wrapped, params, paths=paths)
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


def draw_curves(shapes: ShapePair, truth, count: int, seed: int, side: str, protocol: str):
    """Traced curves with endpoints on ``side``: ``CurvePool``'s seeded draw (``pool``, as ``curvefm reproduce``) or
    2 x count farthest points from vertex ``seed``, consecutive pairs joined (``farthest``, as ``curvefm evaluate``
    and issue 35's protocol)."""
    if protocol == "pool":
        return CurvePool(shapes.mesh_M, shapes.mesh_N, truth, endpoints_on=side).curves(count, seed, exact=False)
    return ground_truth_curves(shapes.mesh_M, shapes.mesh_N, truth, count, seed, endpoints_on=side)


def run_row(pair, shapes: ShapePair, truth, count: int, seed: int, side: str, args) -> dict:
    paths = draw_curves(shapes, truth, count, seed, side, args.curves)
    scored = truth_to_score(truth, paths, seed, side)
    method, method_params = registry.load("method", "combined", None)
    start = time.perf_counter()
    fmaps = method.run(shapes, Hints.from_curves(paths), method_params, lambda *_: None)
    row = {
        "pair": pair.name,
        "dataset": pair.dataset,
        "count": count,
        "seed": seed,
        "endpoints_on": side,
        "vertices": [shapes.mesh_M.n_vertices, shapes.mesh_N.n_vertices],
        "truth": f"{scored.kind}, {len(scored)} rows",
        "solve_s": round(time.perf_counter() - start, 1),
    }
    nn, nn_params = registry.load("converter", "nearest-neighbor", None)
    start_result = convert(shapes, fmaps, nn, nn_params, paths=paths)
    row["start"] = errors(start_result, scored)
    maps = {"start_MN": start_result.maps.p2p_MN, "start_NM": start_result.maps.p2p_NM}
    for name in args.refiners:
        row[name] = refine(shapes, fmaps, paths, scored, name, maps)
        print(
            f"{pair.name} {count} curves, endpoints on the {side}: {name} {row[name]['returned']['mean']} "
            f"(start {row['start']['mean']}, refined {row[name]['refined']['mean']}, kept {row[name]['kept']}, "
            f"{row[name]['seconds']} s)",
            file=sys.stderr,
            flush=True,
        )
    if args.maps_dir is not None:
        args.maps_dir.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(args.maps_dir / f"{pair.dataset}_{pair.name}_{count}_{seed}_{side}.npz", **maps)
    return row


def mean_error(row: dict, key: str) -> float:
    """The row's error (mean of both directions) of the start or of a refiner's returned map."""
    return row[key]["mean"] if key == "start" else row[key]["returned"]["mean"]


def accepted_worse(row: dict, name: str) -> list[str]:
    """The maps (``mean`` of both directions, or either direction) the guard returned refined or stopped although
    they ended worse than the start by more than ``REGRESSION``."""
    if row[name]["kept"] == "initial":
        return []
    returned = row[name]["returned"]
    return [key for key in ("mean", *DIRECTIONS) if returned[key] > (1 + REGRESSION) * row["start"][key]]


def summarise(rows: list[dict]) -> dict:
    regressions, missed, accepted = [], [], []
    for row in rows:
        before = row["start"]["mean"]
        for name in (name for name in REFINERS if name in row):
            entry = {
                "pair": row["pair"],
                "count": row["count"],
                "seed": row["seed"],
                "endpoints_on": row["endpoints_on"],
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
            if worse := accepted_worse(row, name):
                accepted.append(
                    entry | {"worse": worse, "start_both": row["start"], "returned_both": row[name]["returned"]}
                )
    return {
        "rows": len(rows),
        "regressions": len(regressions),
        "regression_list": regressions,
        "accepted_worse": len(accepted),
        "accepted_worse_of": sum(name in row for row in rows for name in REFINERS),
        "accepted_worse_list": accepted,
        "missed_gains": len(missed),
        "missed_gain_list": missed,
        "kept": {name: dict(Counter(row[name]["kept"] for row in rows if name in row)) for name in REFINERS},
        "mean_error": {
            key: round(float(np.mean([mean_error(row, key) for row in rows if key in row])), 5)
            for key in MAPS
            if any(key in row for row in rows)
        },
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_pair_arguments(parser)
    parser.add_argument("--counts", type=int, nargs="+", default=[2, 10], help="curve counts (default 2 10)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0], help="curve draws (default 0)")
    parser.add_argument("--endpoints-on", nargs="+", default=list(ENDPOINT_SIDES), choices=ENDPOINT_SIDES)
    parser.add_argument("--curves", choices=("pool", "farthest"), default="pool", help="how endpoints are drawn")
    parser.add_argument("--refiners", nargs="+", default=list(REFINERS), choices=REFINERS)
    parser.add_argument("--out", type=Path, default=None, help="also write the JSON here (after every row)")
    parser.add_argument("--maps-dir", type=Path, default=None, help="save each row's start and refined maps here")
    args = parser.parse_args()
    report = {
        "benchmark": "refinement_guard",
        "machine": machine(),
        "k": DEFAULT_K,
        "method": "combined",
        "pairs": args.pairs,
        "curves": "traced, " + ("CurvePool (as curvefm reproduce)" if args.curves == "pool" else "farthest points"),
        "counts": args.counts,
        "seeds": args.seeds,
        "endpoints_on": args.endpoints_on,
        "refiners": args.refiners,
        "error": "mean geodesic error / sqrt(area): source_to_target, target_to_source, mean of both; never at a "
        "curve's end",
        "regression": f"returned map's mean worse than the start's by more than {REGRESSION:.0%}",
    }
    report["machine"]["load_avg_1min_before"] = round(os.getloadavg()[0], 2)
    rows, begin = [], time.perf_counter()
    for pair in chosen_pairs(args):
        shapes, truth = ground_truth_pair(pair.source, pair.target)
        for count, seed, side in itertools.product(args.counts, args.seeds, args.endpoints_on):
            rows.append(run_row(pair, shapes, truth, count, seed, side, args))
            report["machine"]["load_avg_1min_after"] = round(os.getloadavg()[0], 2)
            report["seconds"] = round(time.perf_counter() - begin)
            report["summary"] = summarise(rows)
            report["rows"] = rows
            text = json.dumps(report, indent=1)
            if args.out is not None:  # after every row: a long run can be stopped and keeps what it measured
                args.out.parent.mkdir(parents=True, exist_ok=True)
                args.out.write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    limit_blas_threads(1)
    main()
