"""Error against clicks with and without suggested curves, on FAUST 000 -> 011 and cat -> lion (prints JSON).

A simulated person adds curves one at a time, up to ``--curves``, and the pointwise maps ``curvefm match`` hands out
(its defaults: the combined energy, k = 120, the ``nearest-neighbor`` converter with its orthogonal steps) are scored
after each, both directions, by :func:`benchmarks.common.handed_out_errors` (as ``bench_monotone`` scores them): mean
geodesic error / sqrt(area of the shape each map lands on), on every row of the ground truth except those at a
curve's end, on either shape (a map is never scored at the points the person gave):

* **unassisted**: the core issue's protocol (:func:`curvefm.evaluation.ground_truth_curves`): curve i joins
  farthest points 2i and 2i + 1 of the source and their true partners; 4 clicks a curve (two ends on each shape).
* **suggested**: curve i is the suggestion made from the maps of the i - 1 curves before it
  (:func:`curvefm.pointwise.suggest_curve`). The person takes its source ends as they are (snapped to the nearest
  vertex with ground truth), and takes each suggested target end when it lies within ``--tolerance`` (geodesic,
  units of the target's sqrt(area)) of the true partner, else clicks the true partner instead. Clicks: 1 to
  accept, plus 1 for each target end moved. The first suggestion, with no curve yet, comes from zero maps (as a
  new session's): its target ends mean nothing, and the person moves them.

``reaches_unassisted_10_at``: the fewest suggested curves whose error (the mean of both directions) is at most
that of all the unassisted curves.

``--pairs faust_060_071`` runs the held-out pair (FAUST 060 -> 071), on which no rule is tuned.

``--timing``: instead, the time of one suggestion (the round-trip drift and :func:`curvefm.pointwise.suggest_curve`,
as ``GET /sessions/{id}/suggestion`` runs them) on FAUST 000 -> 011 subdivided once (27,554 vertices), from no
curve (zero maps) and from the 10 unassisted curves' maps, and (``*_paths``) the time of tracing the suggested
curve on both shapes, as ``?paths=true`` adds it; the medians of ``--repeats`` runs.

    python -m benchmarks.bench_suggestions [--curves 10] [--tolerance 0.03] [--pairs cat_lion faust_000_011]
    python -m benchmarks.bench_suggestions --timing
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections.abc import Callable

import numpy as np

from benchmarks.bench_scan import subdivided
from benchmarks.common import bench_store, handed_out_errors, machine, shared_data
from curvefm.evaluation import GroundTruth, ground_truth_curves, ground_truth_for
from curvefm.fmap import DEFAULT_K, FunctionalMaps, RoundTripQuality
from curvefm.geometry import Mesh, geodesic_distances, load_mesh, shortest_path
from curvefm.matching import MatchResult, match, pair_with_basis_size
from curvefm.pointwise import suggest_curve
from curvefm.runtime import limit_blas_threads
from curvefm.session.curves import trace_curve
from curvefm.spectral import ShapePair
from curvefm.store import Store

PAIRS = {
    "faust_000_011": ("faust/tr_reg_000.off", "faust/tr_reg_011.off"),
    "cat_lion": ("nonisometric/pyfm_cat_lion/cat-00.off", "nonisometric/pyfm_cat_lion/lion-00.off"),
    "faust_060_071": ("faust/tr_reg_060.off", "faust/tr_reg_071.off"),  # held out: no rule is tuned on it
}
SUITE = ["cat_lion", "faust_000_011"]
DEFAULT_TRACER = "geodesic"  # a new session's
Paths = list[tuple[np.ndarray, np.ndarray]]


def errors(result: MatchResult, truth: GroundTruth, curves: Paths) -> dict[str, float]:
    """The scores of the pointwise maps ``match`` hands out (the product's default conversion)."""
    return handed_out_errors(result.pair, result.maps, truth, curves)


def unassisted(meshes: tuple[Mesh, Mesh], truth: GroundTruth, count: int, store: Store) -> list[dict]:
    curves = ground_truth_curves(*meshes, truth, count)
    return [
        {"curves": n, "clicks": 4 * n} | errors(match(*meshes, curves[:n], store=store), truth, curves[:n])
        for n in range(1, count + 1)
    ]


class Person:
    """Knows the ground truth; judges a suggested target end by its geodesic distance to the true partner."""

    def __init__(self, meshes: tuple[Mesh, Mesh], truth: GroundTruth, tolerance: float):
        self.mesh_M, self.mesh_N = meshes
        self.partner = dict(zip(truth.ids_X.tolist(), truth.ids_Y.tolist(), strict=True))
        self.known = np.fromiter(self.partner, dtype=np.int64)
        self.partners = np.array([self.partner[v] for v in self.known.tolist()], dtype=np.int64)
        self.tolerance = tolerance * np.sqrt(self.mesh_N.area)

    def source_ends(self, suggested: tuple[int, int]) -> list[int]:
        """The suggested source ends snapped to vertices with ground truth, the end never where the start is nor
        where its true partner is the start's: two ends on one vertex, on either shape, would be a curve of no
        length."""
        start = self.known_near(suggested[0], self.known)
        others = (self.known != start) & (self.partners != self.partner[start])
        return [start, self.known_near(suggested[1], self.known[others])]

    def known_near(self, vertex: int, known: np.ndarray) -> int:
        """The vertex of ``known`` nearest to ``vertex`` (itself when it is one)."""
        if vertex in known:
            return vertex
        offsets = self.mesh_M.vertices[known] - self.mesh_M.vertices[vertex]
        return int(known[np.argmin(np.linalg.norm(offsets, axis=1))])

    def target_ends(self, sources: list[int], suggested: tuple[int, int]) -> list[tuple[int, bool]]:
        """The target ends the person settles on, and whether each was moved; suggested ends that would both lie
        on one vertex are both put at their true partners (which differ: see source_ends)."""
        settled = [self.target_end(v, t) for v, t in zip(sources, suggested, strict=True)]
        if settled[0][0] != settled[1][0]:
            return settled
        return [(self.partner[v], self.partner[v] != t) for v, t in zip(sources, suggested, strict=True)]

    def target_end(self, source: int, suggested: int) -> tuple[int, bool]:
        """The target end the person settles on for ``source``, and whether they moved the suggested one."""
        true = self.partner[source]
        if geodesic_distances(self.mesh_N, [true])[0, suggested] <= self.tolerance:
            return suggested, False
        return true, True


def suggested(meshes: tuple[Mesh, Mesh], truth: GroundTruth, count: int, tolerance: float, store: Store) -> list[dict]:
    person, mesh_M, mesh_N = Person(meshes, truth, tolerance), *meshes
    curves: Paths = []
    pair = pair_with_basis_size(store, meshes, DEFAULT_K)
    no_map = np.zeros((DEFAULT_K, DEFAULT_K))
    rows, next_curve = [], suggestion(pair, FunctionalMaps(no_map, no_map), curves)
    clicks = 0
    for n in range(1, count + 1):
        source, target = next_curve
        ends_M = person.source_ends(source)
        settled = person.target_ends(ends_M, target)
        clicks += 1 + sum(moved for _, moved in settled)
        path_N = shortest_path(mesh_N.edge_graph, settled[0][0], settled[1][0])
        curves.append((shortest_path(mesh_M.edge_graph, *ends_M), path_N))
        result = match(mesh_M, mesh_N, curves, store=store)
        moved = [bool(m) for _, m in settled]
        rows.append({"curves": n, "clicks": clicks, "moved": moved} | errors(result, truth, curves))
        next_curve = suggestion(result.pair, result.fmaps, curves)
    return rows


def suggestion(pair: ShapePair, fmaps: FunctionalMaps, curves: Paths) -> tuple[tuple[int, int], tuple[int, int]]:
    drift = RoundTripQuality(pair.mesh_M, pair.basis_M, pair.mesh_N, pair.basis_N).measure(fmaps.C_MN, fmaps.C_NM)
    curves_M = np.concatenate([np.zeros(0, dtype=np.int64), *(path_M for path_M, _ in curves)])
    found = suggest_curve(pair, fmaps.C_MN, fmaps.C_NM, drift.source, curves_M)
    return found.source, found.target


def reached_at(rows: list[dict], goal: float) -> int | None:
    return next((row["curves"] for row in rows if row["mean"] <= goal), None)


def run_pair(source: str, target: str, count: int, tolerance: float, store: Store) -> dict:
    data = shared_data()
    meshes = load_mesh(data / source), load_mesh(data / target)
    truth = ground_truth_for(data / source, data / target, *meshes)
    runs: dict[str, Callable[[], list[dict]]] = {
        "unassisted": lambda: unassisted(meshes, truth, count, store),
        "suggested": lambda: suggested(meshes, truth, count, tolerance, store),
    }
    entry = {name: run() for name, run in runs.items()}
    entry["reaches_unassisted_10_at"] = reached_at(entry["suggested"], entry["unassisted"][-1]["mean"])
    return entry


def suggestion_seconds(curves: int, repeats: int, store: Store) -> dict[str, float]:
    """Median seconds of one suggestion at 27,554 vertices, from no curve and from ``curves`` curves' maps."""
    meshes = subdivided("tr_reg_000", 1), subdivided("tr_reg_011", 1)
    identity = np.arange(meshes[0].n_vertices)
    truth = GroundTruth(identity, identity, "identity", True)
    result = match(*meshes, ground_truth_curves(*meshes, truth, curves), store=store)
    no_maps = FunctionalMaps(np.zeros_like(result.fmaps.C_MN), np.zeros_like(result.fmaps.C_NM))
    timings = {}
    for name, fmaps, given in (("no_curve", no_maps, []), (f"{curves}_curves", result.fmaps, list(result.paths))):
        seconds, traced = [], []
        for _ in range(repeats):
            start = time.perf_counter()
            ends = suggestion(result.pair, fmaps, given)
            seconds.append(time.perf_counter() - start)
            start = time.perf_counter()
            for mesh, (a, b) in zip(meshes, ends, strict=True):
                trace_curve(mesh, waypoints=mesh.file_ids[[a, b]].tolist(), tracer=DEFAULT_TRACER)
            traced.append(time.perf_counter() - start)
        timings[name] = round(float(np.median(seconds)), 4)
        timings[f"{name}_paths"] = round(float(np.median(traced)), 4)
    return {"vertices": meshes[0].n_vertices, "tracer": DEFAULT_TRACER} | timings


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--curves", type=int, default=10, help="curves each person adds")
    parser.add_argument(
        "--tolerance", type=float, default=0.03, help="a suggested end within this of the truth is accepted"
    )
    parser.add_argument("--pairs", nargs="+", choices=sorted(PAIRS), default=SUITE)
    parser.add_argument("--timing", action="store_true", help="time one suggestion at 27,554 vertices instead")
    parser.add_argument("--repeats", type=int, default=5, help="suggestions timed (--timing)")
    args = parser.parse_args()
    report: dict = {"machine": machine(), "tolerance": args.tolerance, "pairs": {}}
    report["machine"]["load_avg_1min_before"] = round(os.getloadavg()[0], 2)
    if args.timing:
        timing = suggestion_seconds(args.curves, args.repeats, bench_store())
        print(json.dumps({"machine": report["machine"], "suggestion_seconds": timing}, indent=2))
        return
    for name in args.pairs:
        report["pairs"][name] = run_pair(*PAIRS[name], args.curves, args.tolerance, bench_store())
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    limit_blas_threads()
    main()
