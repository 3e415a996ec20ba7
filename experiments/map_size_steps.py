"""Which map to hand out and convert, now that the conversion ends with orthogonal steps (issue 35): the default
method's maps below its size switch (50 x 50) and above it (120 x 120, the full-size weights) at every count, each
converted by the default ``nearest-neighbor`` converter, and the 120 x 120 map's pointwise maps given 3 orthogonal
steps in three ways: fitted at 90 functions against the basis's 120 (``120_s90``), against a 150-function basis
(``120_s150``), or converted from its leading 50 x 50 / 90 x 90 block with the converter's own steps (``120_t50``,
``120_t90``). Issue 35's protocol as in :mod:`experiments.orthogonal_steps` (n curves between 2n farthest points on
the source or on the target, scored both ways never at a curve's end), and per candidate and direction the intrinsic
figures a rule could choose by without ground truth: edge stretch (:func:`curvefm.pointwise.edge_stretch`) and the
round-trip drift (mean distance / sqrt(area) from a vertex to its image's image). ``length`` is the curves' total
length on the unit-area source over ``full_size_length(k)`` (the default hands out 120 x 120 from 1 on). ``--extra
SOURCE:TARGET`` adds pairs by path (a TOSCA pair small enough for the exact search, whose steps run). ``--summary
FILE`` prints, from a run's JSON, the mean error of the default before (the 50 x 50 map below the switch, the plain
120 x 120 one from it) and now (``120_t90`` from the switch), with the rows where now is worse by more than 1%.

    nice python -m experiments.map_size_steps [--pairs suite|held-out] [--datasets faust cat-lion]
        [--names PAIR ...] [--extra tosca/wolf1.off:tosca/wolf2.off] [--counts 2 5 10 20] [--out FILE]
    python -m experiments.map_size_steps --summary experiments/map_size_steps.json
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path

import numpy as np

from benchmarks.common import bench_store, machine, shared_data
from curvefm import registry
from curvefm.evaluation import ENDPOINT_SIDES, ground_truth_curves, truth_to_score
from curvefm.fmap import FunctionalMaps, Hints
from curvefm.fmap.combined import full_size_length
from curvefm.geometry import load_mesh
from curvefm.plugins.converters import NearestNeighborParams, convert_nearest_neighbor
from curvefm.pointwise import PointwiseMaps, edge_stretch, orthogonal_steps
from curvefm.runtime import limit_blas_threads
from experiments.common import add_pair_arguments, chosen_pairs, ground_truth_pair
from experiments.orthogonal_steps import errors

STEPS = 3
WIDE = 150  # image-side functions of ``120_s150``
NEVER, ALWAYS = 100_000, 1  # full_size_curves: the 50 x 50 map at any count, the 120 x 120 one


def solve(shapes, paths, full_size_curves: int) -> FunctionalMaps:
    method, params = registry.load("method", "combined", {"full_size_curves": full_size_curves})
    return method.run(shapes, Hints.from_curves(paths), params, lambda *_: None)


def convert(shapes, fmaps: FunctionalMaps, steps: int = STEPS) -> PointwiseMaps:
    return convert_nearest_neighbor(shapes, fmaps, NearestNeighborParams(orthogonal_steps=steps))


def stepped(maps: PointwiseMaps, basis_M, basis_N, k: int) -> PointwiseMaps:
    """``maps`` after :data:`STEPS` orthogonal steps fitted at ``k`` functions on the matched shape's side."""
    return PointwiseMaps(
        p2p_NM=orthogonal_steps(maps.p2p_NM, basis_M, basis_N, k, k, STEPS),
        p2p_MN=orthogonal_steps(maps.p2p_MN, basis_N, basis_M, k, k, STEPS),
    )


def truncated(fmaps: FunctionalMaps, k: int) -> FunctionalMaps:
    return FunctionalMaps(np.ascontiguousarray(fmaps.C_MN[:k, :k]), np.ascontiguousarray(fmaps.C_NM[:k, :k]))


CANDIDATES = ("50", "120", "120_s90", "120_s150", "120_t50", "120_t90")


def candidates(shapes, wide, paths, names) -> dict[str, PointwiseMaps]:
    full = solve(shapes, paths, ALWAYS)
    plain = convert(shapes, full, steps=0)  # the conversion before (no steps at the basis's size)
    make = {
        "50": lambda: convert(shapes, solve(shapes, paths, NEVER)),
        "120": lambda: plain,
        "120_s90": lambda: stepped(plain, shapes.basis_M, shapes.basis_N, 90),
        "120_s150": lambda: stepped(plain, wide[0], wide[1], 120),
        "120_t50": lambda: convert(shapes, truncated(full, 50)),
        "120_t90": lambda: convert(shapes, truncated(full, 90)),
    }
    return {name: make[name]() for name in names}


def figures(shapes, maps: PointwiseMaps) -> dict[str, dict[str, float]]:
    M, N = shapes.mesh_M, shapes.mesh_N
    drift_M = np.linalg.norm(M.vertices - M.vertices[maps.p2p_NM[maps.p2p_MN]], axis=1).mean() / np.sqrt(M.area)
    drift_N = np.linalg.norm(N.vertices - N.vertices[maps.p2p_MN[maps.p2p_NM]], axis=1).mean() / np.sqrt(N.area)
    return {
        "stretch": {
            "source_to_target": round(edge_stretch(M, N, maps.p2p_MN), 5),
            "target_to_source": round(edge_stretch(N, M, maps.p2p_NM), 5),
        },
        "drift": {"source": round(float(drift_M), 5), "target": round(float(drift_N), 5)},
    }


def curves_length(shapes, paths) -> float:
    vertices = shapes.mesh_M.vertices
    total = sum(float(np.linalg.norm(np.diff(vertices[path_M], axis=0), axis=1).sum()) for path_M, _ in paths)
    return total / float(np.sqrt(shapes.mesh_M.area))


def row(name: str, shapes, wide, truth, count: int, side: str, names) -> dict:
    paths = ground_truth_curves(shapes.mesh_M, shapes.mesh_N, truth, count, 0, endpoints_on=side)
    scored = truth_to_score(truth, paths, 0, side)
    out = {"pair": name, "count": count, "endpoints_on": side}
    out["length"] = round(curves_length(shapes, paths) / full_size_length(shapes.basis_M.k), 3)
    out["maps"] = {
        key: {"errors": errors(shapes, maps, scored), **figures(shapes, maps)}
        for key, maps in candidates(shapes, wide, paths, names).items()
    }
    return out


def wide_bases(source: str, target: str):
    data, store = shared_data(), bench_store()
    return tuple(store.ensure_basis(load_mesh(data / path), WIDE) for path in (source, target))


DIRECTIONS = ("source_to_target", "target_to_source")


def chosen(row: dict, full: str) -> list[float]:
    """Both errors of the map the default hands out: the 50 x 50 one below the length switch, else ``full``."""
    return [row["maps"]["50" if row["length"] < 1 else full]["errors"][d] for d in DIRECTIONS]


def summary(path: Path) -> dict:
    rows = json.loads(path.read_text())["rows"]
    before, now = [chosen(r, "120") for r in rows], [chosen(r, "120_t90") for r in rows]
    worse = [
        f"{r['pair']} {r['count']} {r['endpoints_on']} {d}: {b[i]} -> {n[i]}"
        for r, b, n in zip(rows, before, now, strict=True)
        for i, d in enumerate(DIRECTIONS)
        if n[i] > 1.01 * b[i]
    ]
    return {"rows": len(rows), "before": _mean(before), "now": _mean(now), "worse": worse}


def _mean(errors: list[list[float]]) -> float:
    return round(float(np.mean(errors)), 5)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_pair_arguments(parser)
    parser.add_argument("--extra", nargs="*", default=[], help="SOURCE:TARGET paths in the shared data")
    parser.add_argument("--counts", type=int, nargs="+", default=[2, 5, 10, 20])
    parser.add_argument("--candidates", nargs="+", default=list(CANDIDATES), choices=CANDIDATES)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--summary", type=Path, default=None, help="summarise this run's JSON instead")
    args = parser.parse_args()
    if args.summary is not None:
        print(json.dumps(summary(args.summary), indent=1))
        return
    pairs = [(p.name, p.source, p.target) for p in chosen_pairs(args)] if args.names != ["none"] else []
    pairs += [(extra.replace(":", "->"), *extra.split(":")) for extra in args.extra]
    report = {"experiment": "map_size_steps", "machine": machine(), "pairs": args.pairs, "steps": STEPS, "rows": []}
    report["candidates"] = args.candidates
    for name, source, target in pairs:
        wide = wide_bases(source, target) if "120_s150" in args.candidates else None
        shapes, truth = ground_truth_pair(source, target)
        for count, side in itertools.product(args.counts, ENDPOINT_SIDES):
            report["rows"].append(row(name, shapes, wide, truth, count, side, args.candidates))
            print(json.dumps(report["rows"][-1]), file=sys.stderr, flush=True)
            if args.out is not None:
                args.out.write_text(json.dumps(report, indent=1) + "\n")
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    limit_blas_threads(1)
    main()
