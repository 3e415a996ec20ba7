"""One curve that cannot flip (issue 35): the landmark prior with each curve's side (``side_curves``).

The issue's protocol: n curves between 2n farthest points chosen **on the target** among the vertices with a
ground-truth partner (the first from ``--seed-vertices``; 0 is the issue's), consecutive pairs joined by shortest
paths on each shape, the source endpoints their true images. The default method (``combined``, k = 120, nearest
neighbours with both maps) is run with ``side_curves`` 0 (``before``: the prior from the endpoints alone), the
default when measured, 1 (``after``: with one curve the prior also keeps the curve's side where the sides agree
under it, ``SIDE_AGREEMENT``) and, with two curves, 2 (``sides_at_2``: the same with two curves; the default
since). Scored both ways (mean geodesic error / sqrt(area) of the shape measured on) at the ground-truth rows whose
vertices are not curve endpoints; ``target_to_source`` is the issue's figure. Where the variants are the same
computation (more curves than ``after``'s 1) ``after`` is measured once and ``before`` repeats it.
experiments/curve_side.json holds the suite's runs with one curve, experiments/curve_side_2_10.json those with 2
and 10; the ``_held_out`` files the same on held-out pairs (``--pairs held-out``, by default four of them).

    nice python -m experiments.curve_side [--pairs suite|held-out] [--counts 1 2 10] [--seed-vertices 0 1000 4000]
        [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from benchmarks.common import bench_store, machine
from curvefm.evaluation import ground_truth_curves, truth_away_from_ends
from curvefm.evaluation.ground_truth import GroundTruth
from curvefm.evaluation.reproduce.datasets import Pair
from curvefm.fmap import DEFAULT_K, SIDE_CURVES
from curvefm.matching import match
from curvefm.runtime import limit_blas_threads
from experiments.common import add_pair_arguments, chosen_pairs, ground_truth_pair
from experiments.pin_rule import DIRECTIONS, errors

DEFAULT_NAMES = {
    "suite": ["tr_reg_000->tr_reg_011", "cat-00->lion-00"],
    "held-out": ["tr_reg_060->tr_reg_071", "tr_reg_080->tr_reg_091", "dog0->dog2", "horse0->horse5"],
}
VARIANTS = {"after": 1, "before": 0, "sides_at_2": 2}  # "after": the default when measured; 2 since


def target_chosen_curves(pair, truth: GroundTruth, count: int, seed_vertex: int):
    """The issue's curves, farthest points on the target from ``seed_vertex`` (a target vertex id)."""
    swapped = GroundTruth(truth.ids_Y, truth.ids_X, truth.kind, truth.dense)
    curves = ground_truth_curves(pair.mesh_N, pair.mesh_M, swapped, count, seed_vertex % pair.mesh_N.n_vertices)
    return [(path_M, path_N) for path_N, path_M in curves]


def run_row(pair: Pair, count: int, seed_vertex: int) -> dict:
    shapes, truth = ground_truth_pair(pair.source, pair.target)
    curves = target_chosen_curves(shapes, truth, count, seed_vertex)
    scored = truth_away_from_ends(truth, curves)
    row = {
        "dataset": pair.dataset,
        "pair": pair.name,
        "curves": count,
        "seed_vertex": seed_vertex,
    }
    for variant, side_curves in VARIANTS.items():
        if variant == "sides_at_2" and count != 2:
            continue  # the same computation as ``after`` with one curve, as ``before`` with more than two
        if variant == "before" and count > VARIANTS["after"]:
            row[variant] = row["after"]  # the same computation: no side term with more curves than after's
            continue
        result = match(
            shapes.mesh_M,
            shapes.mesh_N,
            curves,
            k=DEFAULT_K,
            store=bench_store(),
            method="combined",
            method_params={"side_curves": side_curves},
        )
        row[variant] = errors(shapes, result.maps, scored)
    print(json.dumps(row), file=sys.stderr, flush=True)
    return row


def summarise(rows: list[dict]) -> list[dict]:
    """Mean error per (curve count, variant), the issue's direction and the other."""
    cells = []
    for count in sorted({r["curves"] for r in rows}):
        chosen = [r for r in rows if r["curves"] == count]
        cell: dict = {"curves": count, "runs": len(chosen)}
        for variant in VARIANTS:
            if all(variant in r for r in chosen):
                cell[variant] = {
                    d: round(sum(r[variant][d] for r in chosen) / len(chosen), 5) for d in (*DIRECTIONS, "mean")
                }
        cells.append(cell)
    return cells


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[1, 2, 10])
    parser.add_argument("--seed-vertices", type=int, nargs="+", default=[0, 1000, 4000])
    parser.add_argument("--out", type=Path, default=None)
    add_pair_arguments(parser)
    args = parser.parse_args()
    args.names = args.names or DEFAULT_NAMES[args.pairs]
    pairs = chosen_pairs(args)
    report = {"benchmark": "curve_side", "machine": machine(), "k": DEFAULT_K, "side_curves": SIDE_CURVES}
    report["pairs"] = args.pairs
    report["machine"]["load_avg_1min_before"] = round(os.getloadavg()[0], 2)
    begin, rows = time.perf_counter(), []
    for count in args.counts:
        seeds = args.seed_vertices if count <= 2 else args.seed_vertices[:1]
        for pair in pairs:
            for seed_vertex in seeds:
                rows.append(run_row(pair, count, seed_vertex))
                done = {"seconds": round(time.perf_counter() - begin), "summary": summarise(rows), "rows": rows}
                text = json.dumps(report | done, indent=1)
                if args.out is not None:  # after every row: a long run can be stopped and keeps what it measured
                    args.out.write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    limit_blas_threads(1)
    main()
