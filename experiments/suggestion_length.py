"""Longer suggested curves, screened for issue 35 (docs/accuracy.md#suggested-curves): the simulated person of
``benchmarks/bench_suggestions.py`` (tolerance 0.03) with the later suggestions' end rule swapped, on one pair, up
to ``--curves``; prints one JSON object: each curve's error, clicks and the curves' total length after it (units of
sqrt(area)). ``faust_060_071`` is held out: it checks a variant, never chooses one.

The first suggestion is always the product's (away from the start's mirror twin), and so is every start. Variants
of the end, while the curves' total length on the unit-area source is below the map-size switch (``sqrt(k / pi)``,
6.2 at k = 120; at and above it the product's rule):

* ``base``: the product's rule, ``sqrt(drift) min(d, d_start)``;
* ``reach:m``: that score among the vertices at least ``(switch - total) / (m - curves)`` from the start (at most
  0.95 of the farthest), so the total crosses the switch at curve m;
* ``late:m[:j]``: the product's rule for curves 2 to j - 1, ``reach:m`` from the j-th (default 4);
* ``power:a``: ``sqrt(drift) min(d, d_start)^a d_start^(1 - a)`` (longer curves for a < 1).

    python -m experiments.suggestion_length VARIANT PAIR [--curves 6]
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

import benchmarks.bench_suggestions as bench
from benchmarks.common import bench_store, shared_data
from curvefm.evaluation import ground_truth_for
from curvefm.fmap import RoundTripQuality
from curvefm.fmap.combined import full_size_length
from curvefm.geometry import Mesh, load_mesh
from curvefm.pointwise import suggest_curve
from curvefm.pointwise.conversion import pointwise_from_both
from curvefm.pointwise.suggestion import _apart, _distances
from curvefm.runtime import limit_blas_threads

SWITCH = full_size_length(120)


def length(mesh: Mesh, path: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(mesh.vertices[path], axis=0), axis=1).sum() / np.sqrt(mesh.area))


def end_score(
    variant: str, drift: np.ndarray, from_curves: np.ndarray, from_start: np.ndarray, curves: int, total: float
):
    weight, nearest = np.sqrt(np.maximum(drift, 0.0)), np.minimum(from_curves, from_start)
    kind, _, value = variant.partition(":")
    value, _, first = value.partition(":")
    if total >= SWITCH or kind == "base" or (kind == "late" and curves + 1 < int(first or 4)):
        return weight * nearest
    if kind == "power":
        return weight * nearest ** float(value) * from_start ** (1 - float(value))
    wanted = min((SWITCH - total) / max(int(value) - curves, 1), 0.95 * from_start.max())
    return np.where(from_start >= wanted, weight * nearest, from_start / from_start.max() - 1.0)


def make_suggestion(variant: str, totals: list[float]):
    def suggestion(pair, fmaps, curves):
        drift = RoundTripQuality(pair.mesh_M, pair.basis_M, pair.mesh_N, pair.basis_N).measure(fmaps.C_MN, fmaps.C_NM)
        curves_M = np.concatenate([np.zeros(0, dtype=np.int64), *(path_M for path_M, _ in curves)])
        total = sum(length(pair.mesh_M, path_M) for path_M, _ in curves)
        totals.append(total)
        print(f"# {variant}: {len(curves)} curves, length {total:.2f}", file=sys.stderr, flush=True)
        found = suggest_curve(pair, fmaps.C_MN, fmaps.C_NM, drift.source, curves_M)
        if not curves:
            return found.source, found.target
        start = found.source[0]
        from_start = _distances(pair.mesh_M, np.array([start]))
        score = end_score(variant, drift.source, _distances(pair.mesh_M, curves_M), from_start, len(curves), total)
        rows = np.array([start, int(np.argmax(score))])
        images = pointwise_from_both(fmaps.C_NM, fmaps.C_MN, pair.basis_N, pair.basis_M, rows=rows)
        return (int(rows[0]), int(rows[1])), _apart(pair.mesh_N, int(images[0]), int(images[1]))

    return suggestion


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("variant")
    parser.add_argument("pair", choices=bench.PAIRS)
    parser.add_argument("--curves", type=int, default=6)
    args = parser.parse_args()
    totals: list[float] = []
    bench.suggestion = make_suggestion(args.variant, totals)
    source, target = bench.PAIRS[args.pair]
    data = shared_data()
    meshes = load_mesh(data / source), load_mesh(data / target)
    truth = ground_truth_for(data / source, data / target, *meshes)
    rows = bench.suggested(meshes, truth, args.curves, 0.03, bench_store())
    rows = [row | {"total_length": round(total, 2)} for row, total in zip(rows, totals[1:], strict=True)]
    print(json.dumps({"variant": args.variant, "pair": args.pair, "rows": rows}, indent=1))


if __name__ == "__main__":
    limit_blas_threads()
    main()
