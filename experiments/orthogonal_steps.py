"""Orthogonal steps in the ``nearest-neighbor`` conversion (issue 35): the default method's maps converted with 0
steps (the conversion before) and with 3 and 5 steps with 30 more functions on the image side (``ORTHOGONAL_EXTRA``;
none where the basis has no more functions than the map), on issue 35's protocol: n curves between 2n farthest points
chosen on the source and, in a row of their own, on the target, among the vertices with a ground-truth partner,
consecutive pairs joined. Scored both ways (mean geodesic error / sqrt(area) of the shape measured on) at the
ground-truth rows that are not a curve's end. The square steps of docs/decisions.md's table were measured before the
steps were limited to a larger image side, which leaves nothing to measure here. ``--out`` writes the JSON
(experiments/orthogonal_steps.json: ``--datasets faust cat-lion --counts 2 10``).

    nice python -m experiments.orthogonal_steps [--pairs suite|held-out] [--datasets faust cat-lion]
        [--names PAIR ...] [--counts 2 10] [--out FILE]
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path
from unittest import mock

from benchmarks.common import machine
from curvefm import registry
from curvefm.evaluation import ENDPOINT_SIDES, evaluate_map, ground_truth_curves, truth_to_score
from curvefm.fmap import Hints
from curvefm.plugins.converters import NearestNeighborParams, convert_nearest_neighbor
from curvefm.pointwise import conversion
from curvefm.runtime import limit_blas_threads
from experiments.common import add_pair_arguments, chosen_pairs, ground_truth_pair

VARIANTS = {"none": (0, 30), "extra_3": (3, 30), "extra_5": (5, 30)}  # steps, extra functions


def row(pair, shapes, truth, count: int, side: str) -> dict:
    paths = ground_truth_curves(shapes.mesh_M, shapes.mesh_N, truth, count, 0, endpoints_on=side)
    scored = truth_to_score(truth, paths, 0, side)
    method, params = registry.load("method", "combined", None)
    fmaps = method.run(shapes, Hints.from_curves(paths), params, lambda *_: None)
    out = {"pair": pair.name, "dataset": pair.dataset, "count": count, "endpoints_on": side}
    out["map"] = list(fmaps.C_MN.shape)
    for name, (steps, extra) in VARIANTS.items():
        with mock.patch.object(conversion, "ORTHOGONAL_EXTRA", extra):
            maps = convert_nearest_neighbor(shapes, fmaps, NearestNeighborParams(orthogonal_steps=steps))
        out[name] = errors(shapes, maps, scored)
    return out


def errors(shapes, maps, scored) -> dict[str, float]:
    """Mean geodesic error / sqrt(area) of both maps, each on the shape it maps to."""
    reverse = (scored.ids_Y, scored.ids_X)
    return {
        "source_to_target": round(evaluate_map(maps.p2p_MN, scored, shapes.mesh_N).mean_area, 5),
        "target_to_source": round(evaluate_map(maps.p2p_NM, reverse, shapes.mesh_M).mean_area, 5),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_pair_arguments(parser)
    parser.add_argument("--counts", type=int, nargs="+", default=[2, 10])
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    report = {"experiment": "orthogonal_steps", "machine": machine(), "pairs": args.pairs, "variants": VARIANTS}
    rows = []
    for pair in chosen_pairs(args):
        shapes, truth = ground_truth_pair(pair.source, pair.target)
        for count, side in itertools.product(args.counts, ENDPOINT_SIDES):
            rows.append(row(pair, shapes, truth, count, side))
            print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    report["rows"] = rows
    text = json.dumps(report, indent=1)
    if args.out is not None:
        args.out.write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    limit_blas_threads(1)
    main()
