"""Which of the curves' vertices should the refiners pin? (:class:`curvefm.pointwise.CurvePins`)

The issue's protocol (issue 35): n curves between 2n farthest points chosen **on the target** among the vertices
with a ground-truth partner (:func:`curvefm.evaluation.ground_truth_curves` on the swapped pair), consecutive
pairs joined by shortest paths on each shape, the source endpoints the true images. From the default method's
(``combined``) functional maps at k = 120, ``zoomout`` and ``rhm`` (defaults) through
:func:`curvefm.matching.convert` and its guard, under each pin rule:

* ``all``: every vertex of a curve hard-pinned to the partner curve's vertex at the same normalised arc length
  (the rule before issue 35);
* ``ends``: the curves' endpoints hard-pinned, their interiors free;
* ``softW``: the endpoints hard, the interiors' arc-length partners blended into ZoomOut's fits with weight W
  (its ``curve_interior_weight``; for ``rhm``, its ZoomOut start's), 0 under the other rules.

Every map is scored in both directions (``source_to_target``: each source vertex's target vertex, error on the
target; ``target_to_source`` likewise), mean geodesic error / sqrt(area of the shape it is measured on), at the
ground-truth rows whose vertices are not curve endpoints (never at the points the user gave). Each refiner records
the map it produced (``refined``), the map the guard returned (``returned``) and which it kept; the start is the
``nearest-neighbor`` converter's maps, which the guard compares with. Prints one JSON object (``--out`` also writes
it); experiments/pin_rule.json and experiments/pin_rule_held_out.json are its output.

    nice python -m experiments.pin_rule [--pairs suite|held-out] [--names tr_reg_000->tr_reg_011 cat-00->lion-00]
        [--datasets faust cat-lion] [--counts 2 10] [--rules all ends soft0.5] [--refiners zoomout rhm] [--out FILE]
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.common import machine
from curvefm import registry
from curvefm.errors import InvalidInput
from curvefm.evaluation import ground_truth_curves, truth_away_from_ends
from curvefm.evaluation.ground_truth import GroundTruth
from curvefm.evaluation.metrics import map_geodesic_errors
from curvefm.fmap import DEFAULT_K, Hints
from curvefm.matching import convert
from curvefm.pointwise import CurvePins
from curvefm.runtime import limit_blas_threads
from experiments.common import add_pair_arguments, chosen_pairs, ground_truth_pair
from experiments.refinement_guard import recording

DIRECTIONS = ("source_to_target", "target_to_source")


@contextlib.contextmanager
def pin_rule(rule: str):
    """While the block runs: every curve vertex hard-pinned by arc length for ``all``, the ends only otherwise."""
    original = CurvePins.__dict__["from_curves"]

    def from_curves(cls, mesh_M, mesh_N, paths, hard_interiors=False):
        return original.__func__(cls, mesh_M, mesh_N, paths, hard_interiors=rule == "all")

    CurvePins.from_curves = classmethod(from_curves)
    try:
        yield
    finally:
        CurvePins.from_curves = original


def rule_params(rule: str, name: str) -> dict:
    """The converter's parameters under ``rule``: the weight of the interiors' arc-length partners in ZoomOut's fits
    (RHM's ZoomOut start for ``rhm``), W for ``softW``, else 0."""
    weight = {"curve_interior_weight": float(rule[4:]) if rule.startswith("soft") else 0.0}
    return {"init_zoomout": weight} if name == "rhm" else weight


def target_chosen_curves(pair, truth: GroundTruth, count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The issue's curves: endpoints by farthest points on the target among vertices with a partner."""
    swapped = GroundTruth(truth.ids_Y, truth.ids_X, truth.kind, truth.dense)
    return [(path_M, path_N) for path_N, path_M in ground_truth_curves(pair.mesh_N, pair.mesh_M, swapped, count)]


def errors(pair, maps, truth: GroundTruth) -> dict:
    """Mean geodesic error / sqrt(area) both ways and their mean."""
    to_target = map_geodesic_errors(maps.p2p_MN, truth, pair.mesh_N).mean() / np.sqrt(pair.mesh_N.area)
    to_source = map_geodesic_errors(maps.p2p_NM, (truth.ids_Y, truth.ids_X), pair.mesh_M).mean()
    both = {
        DIRECTIONS[0]: round(float(to_target), 5),
        DIRECTIONS[1]: round(float(to_source / np.sqrt(pair.mesh_M.area)), 5),
    }
    return both | {"mean": round(0.5 * (both[DIRECTIONS[0]] + both[DIRECTIONS[1]]), 5)}


def refine(pair, fmaps, curves, truth, name: str, rule: str) -> dict:
    plugin, params = registry.load("converter", name, rule_params(rule, name))
    wrapped, box = recording(plugin)
    start = time.perf_counter()
    result = convert(pair, fmaps, wrapped, params, paths=curves)
    return {
        "refined": errors(pair, box["maps"], truth),
        "returned": errors(pair, result.maps, truth),
        "kept": result.kept,
        "reason": result.reason,
        "seconds": round(time.perf_counter() - start, 1),
    }


def run_row(source: str, target: str, count: int, rules, refiners) -> dict:
    pair, truth = ground_truth_pair(source, target)
    curves = target_chosen_curves(pair, truth, count)
    scored = truth_away_from_ends(truth, curves)
    method, method_params = registry.load("method", "combined", None)
    fmaps = method.run(pair, Hints.from_curves(curves), method_params, lambda *_: None)
    nn, nn_params = registry.load("converter", "nearest-neighbor", None)
    row = {"pair": f"{source} -> {target}", "curves": count, "scored_rows": len(scored), "truth": truth.kind}
    row["start"] = errors(pair, nn.run(pair, fmaps, nn_params), scored)
    for rule in rules:
        with pin_rule(rule):
            row[rule] = {name: refine(pair, fmaps, curves, scored, name, rule) for name in refiners}
        summary = ", ".join(f"{n} {row[rule][n]['refined']['mean']} ({row[rule][n]['kept']})" for n in refiners)
        print(
            f"{row['pair']} {count} curves, {rule}: start {row['start']['mean']}, {summary}",
            file=sys.stderr,
            flush=True,
        )
    return row


def summarise(rows: list[dict], rules, refiners) -> dict:
    """Per rule and refiner: mean of each direction over the rows, per curve count; and how often the guard
    returned a map worse than the start (by more than 1%, mean of both directions)."""
    summary = {}
    for rule in rules:
        for name in refiners:
            entry = {}
            for count in sorted({r["curves"] for r in rows}):
                chosen = [r[rule][name] for r in rows if r["curves"] == count]
                entry[f"{count} curves"] = {
                    stage: {d: round(float(np.mean([c[stage][d] for c in chosen])), 5) for d in (*DIRECTIONS, "mean")}
                    for stage in ("refined", "returned")
                }
            entry["guard_returned_worse"] = sum(
                r[rule][name]["returned"]["mean"] > 1.01 * r["start"]["mean"] for r in rows
            )
            summary[f"{rule} {name}"] = entry
    return summary


def finished(rows: list[dict], args: argparse.Namespace, begin: float) -> dict:
    return {
        "load_avg_1min_now": round(os.getloadavg()[0], 2),
        "seconds": round(time.perf_counter() - begin),
        "summary": summarise(rows, args.rules, args.refiners),
        "rows": rows,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_pair_arguments(parser)
    parser.add_argument("--counts", type=int, nargs="+", default=[2, 10])
    parser.add_argument("--rules", nargs="+", default=["all", "ends", "soft0.5"])
    parser.add_argument("--refiners", nargs="+", default=["zoomout", "rhm"])
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    pairs = chosen_pairs(args)
    report = {"benchmark": "pin_rule", "machine": machine(), "k": DEFAULT_K, "method": "combined", "pairs": args.pairs}
    report["machine"]["load_avg_1min_before"] = round(os.getloadavg()[0], 2)
    begin = time.perf_counter()
    rows = []
    for pair, count in itertools.product(pairs, args.counts):
        try:
            rows.append(run_row(pair.source, pair.target, count, args.rules, args.refiners))
        except InvalidInput as error:  # sparse truth: too few landmarks for this many curves
            print(f"{pair.name} {count} curves skipped: {error}", file=sys.stderr, flush=True)
        text = json.dumps(report | finished(rows, args, begin), indent=1)
        if args.out is not None:  # after every row: a long run can be stopped and keeps what it measured
            args.out.write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    limit_blas_threads(1)
    main()
