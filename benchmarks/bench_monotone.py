"""Monotone in clicks: does adding a curve ever make the default map worse?

A simulated person adds curves one at a time in the order the evaluation protocol (and a person spreading clicks
over the shapes) gives them: 2n farthest-point endpoints among the vertices with a known partner, consecutive pairs
joined (:func:`curvefm.evaluation.ground_truth_curves`; the first 2n of a farthest-point sequence are the sequence
for n curves, so each run is a prefix of the next). Each seed starts the farthest-point sampling at another vertex;
``source`` chooses the endpoints on the pair's source and scores the source -> target map on the target,
``target`` does both the other way round (the pair reversed). After each click each functional map below is
converted as ``curvefm match`` converts it (:func:`curvefm.matching.handed_out`: the ``nearest-neighbor`` converter
with its orthogonal steps) and the source -> target pointwise map scored as ``bench_suggestions`` scores its maps
(:func:`benchmarks.common.handed_out_errors`): the mean geodesic error / sqrt(area) at the ground-truth rows the
curves do not end at (a landmark truth: at the landmarks held out of the endpoints). The runs recorded before
(``experiments/monotone_rule*.json``) scored plain nearest neighbours of ``C_NM`` on a 1,000-row sample of the truth
instead (``curvefm reproduce``'s scorer).

The maps after each click, all from one solver per run (one landmark prior per set of endpoints):

- ``default``: what the ``combined`` method hands out for these curves (its size and energy switches applied);
- ``prior_size``: the combined energy handed out at the landmark prior's 50 x 50 (the default until the curves'
  length reaches :func:`curvefm.fmap.combined.full_size_length`; until 2026-11-28, below 20 curves);
- ``full_size``: the combined energy handed out whole with the full-size weights (the default from then on);
- ``curves``: the curve energy alone (the fallback of strongly non-isometric pairs).

With ``--figures`` each click also records the intrinsic figures a switch could read (the curves' endpoint
distortion, their total length on a unit-area source, the frequencies that length resolves) and the error at
intermediate sizes, for experiments/monotone_rule.py. Prints one JSON object: per run the errors after each click,
and per map the share of clicks that made it worse and the largest increase (absolute and relative).

    CURVEFM_SHARED_DATA=../shared/data python -m benchmarks.bench_monotone [--curves 6] [--seeds 2]
        [--pairs suite|held-out] [--datasets faust cat-lion] [--directions source target] [--figures]
        [--default-only]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from dataclasses import dataclass, replace

import numpy as np

from benchmarks.common import bench_store, handed_out_errors, machine, shared_data
from curvefm.evaluation import GroundTruth, ground_truth_curves, ground_truth_for
from curvefm.evaluation.protocol import Curves, held_out_landmarks
from curvefm.evaluation.reproduce.datasets import Pair
from curvefm.fmap import DEFAULT_K, CombinedMapSolver, CurveMapSolver, FunctionalMaps
from curvefm.fmap.combined import DEFAULT_COMBINED_ALPHA, curves_alone_suffice, curves_distortion
from curvefm.geometry import load_mesh
from curvefm.matching import handed_out, pair_with_basis_size
from curvefm.runtime import limit_blas_threads
from curvefm.spectral import ShapePair
from experiments.common import add_pair_arguments, chosen_pairs

MAPS = ("default", "prior_size", "full_size", "curves")
FIGURE_SIZES = (50, 70, 90, 120)  # the combined map (default weights) handed out at these sizes, with --figures
NEVER = 10**9  # a full-size switch no run reaches


@dataclass
class LoadedPair:
    pair: Pair
    shapes: ShapePair
    truth: GroundTruth


@dataclass
class Run:
    loaded: LoadedPair
    seed: int
    direction: str

    @property
    def seed_vertex(self) -> int:
        """Seed 0 starts at vertex 0 (the protocol's order); others at a seeded random vertex."""
        n = self.loaded.shapes.mesh_M.n_vertices
        return 0 if self.seed == 0 else int(np.random.default_rng(self.seed).integers(n))

    def max_curves(self) -> int:
        """The most curves the protocol can draw on this pair (a landmark truth keeps a third for scoring)."""
        truth = self.loaded.truth
        known = np.unique(truth.ids_X)
        return int(np.count_nonzero(~np.isin(known, held_out_landmarks(truth, 0)))) // 2


def loaded_pair(pair: Pair, direction: str) -> LoadedPair:
    chosen = pair if direction == "source" else replace(pair, source=pair.target, target=pair.source)
    data = shared_data()
    meshes = load_mesh(data / chosen.source), load_mesh(data / chosen.target)
    truth = ground_truth_for(data / chosen.source, data / chosen.target, *meshes)
    return LoadedPair(chosen, pair_with_basis_size(bench_store(), meshes, DEFAULT_K), truth)


_SCORED: dict[tuple[int, bytes], float] = {}  # the last click's errors by the maps' content: equal maps convert once


def error(run: Run, fmaps: FunctionalMaps, curves: Curves) -> float:
    """The error source -> target of the pointwise map ``curvefm match`` hands out for ``fmaps``."""
    key = (len(curves), hashlib.sha1(fmaps.C_MN.tobytes() + fmaps.C_NM.tobytes()).digest())
    if key in _SCORED:
        return _SCORED[key]
    shapes = run.loaded.shapes
    maps = handed_out(shapes, fmaps)
    scored = handed_out_errors(shapes, maps, run.loaded.truth, curves, ["source_to_target"])["source_to_target"]
    if len(_SCORED) > 64:
        _SCORED.clear()
    _SCORED[key] = scored
    return scored


def solved(solver: CombinedMapSolver, full_size_curves: int | None) -> FunctionalMaps:
    """The solver's maps as they would be handed out with this full-size switch (None: the default rule); the
    prior is kept."""
    solver.full_size_curves = full_size_curves
    solver._stale.update(("MN", "NM"))  # the weights and size changed, the curves did not
    fmaps = FunctionalMaps(solver.C_MN, solver.C_NM)
    solver.full_size_curves = None
    return fmaps


def click_errors(run: Run, combined: CombinedMapSolver, curve_energy: CurveMapSolver, curves, args) -> dict:
    shapes = run.loaded.shapes
    if curves_alone_suffice(shapes.basis_M, shapes.basis_N, curves):
        default = "curves"
    else:
        default = "full_size" if combined.full_size else "prior_size"
    scorers = {
        "prior_size": lambda: error(run, solved(combined, NEVER), curves),
        "full_size": lambda: error(run, solved(combined, 1), curves),
        "curves": lambda: error(run, FunctionalMaps(curve_energy.C_MN, curve_energy.C_NM), curves),
    }
    errors = {name: scorers[name]() for name in sorted({default, *recorded_maps(args)} - {"default"})}
    errors["default"] = errors[default]
    if args.figures:
        errors |= size_errors(run, combined, curves) | intrinsic_figures(shapes, curves)
    return errors


def recorded_maps(args) -> tuple[str, ...]:
    """With ``--default-only`` the default and the 50 x 50 map (what the size switch replaced): a third of the
    conversions."""
    return ("default", "prior_size") if args.default_only else MAPS


def size_errors(run: Run, combined: CombinedMapSolver, curves: Curves) -> dict:
    """The full-size map cut to each of FIGURE_SIZES, and the default weights' map handed out whole."""
    full = solved(combined, 1)
    out = {
        f"full_size_{s}": error(run, FunctionalMaps(full.C_MN[:s, :s], full.C_NM[:s, :s]), curves)
        for s in FIGURE_SIZES[1:-1]
    }
    weights = combined.full_size_alpha, combined.full_size_kernel_weight
    combined.full_size_alpha, combined.full_size_kernel_weight = combined.alpha, combined.kernel_weight
    out["prior_weights_120"] = error(run, solved(combined, 1), curves)
    combined.full_size_alpha, combined.full_size_kernel_weight = weights
    return out


def intrinsic_figures(shapes, curves) -> dict:
    """What a switch could read of the curves: the endpoints' landmark distortion, the curves' total length on
    the unit-area source (``length``), and how many of the source's eigenfunctions that length resolves: those with
    ``lam <= (pi length)^2``, half a wavelength no shorter than the spacing (area / length) of curves that total
    length would have if spread evenly."""
    mesh = shapes.mesh_M
    length = sum(float(np.linalg.norm(np.diff(mesh.vertices[path], axis=0), axis=1).sum()) for path, _ in curves)
    length /= np.sqrt(mesh.area)
    evals = shapes.basis_M.evals
    return {
        "distortion": round(curves_distortion(shapes.basis_M, shapes.basis_N, curves), 4),
        "length": round(length, 3),
        "resolved": int(np.count_nonzero(evals <= (np.pi * length) ** 2)),
    }


def run_clicks(run: Run, count: int, args) -> dict:
    shapes = run.loaded.shapes
    curves = ground_truth_curves(shapes.mesh_M, shapes.mesh_N, run.loaded.truth, count, run.seed_vertex)
    solver_args = (shapes.mesh_M.vertices, shapes.basis_M, shapes.mesh_N.vertices, shapes.basis_N)
    # as a session builds it: the area for the size switch, the meshes for the curves' sides in the prior
    combined = CombinedMapSolver(
        *solver_args, k=DEFAULT_K, interactive=True, source_area=shapes.mesh_M.area, meshes=shapes.meshes
    )
    curve_energy = CurveMapSolver(*solver_args, k=DEFAULT_K, alpha=DEFAULT_COMBINED_ALPHA, interactive=True)
    clicks = []
    for n, (path_M, path_N) in enumerate(curves, start=1):
        combined.add_curve(path_M, path_N)
        curve_energy.add_curve(path_M, path_N)
        clicks.append(click_errors(run, combined, curve_energy, curves[:n], args))
    name = run.loaded.pair.name
    print(f"{name} seed {run.seed} {run.direction}: {len(curves)} clicks", file=sys.stderr, flush=True)
    out = {"pair": name, "dataset": run.loaded.pair.dataset, "seed": run.seed, "direction": run.direction}
    out["errors"] = {m: [c[m] for c in clicks] for m in recorded_maps(args)}
    if args.figures:
        out["figures"] = [{key: value for key, value in c.items() if key not in MAPS} for c in clicks]
    print(json.dumps(out), file=sys.stderr, flush=True)  # a stopped benchmark keeps the runs it finished
    return out


def worsening(series: list[list[float]]) -> dict:
    """Over every click after the first: the share that raised the error, and the largest rises."""
    steps = [(b - a, b / a - 1) for errors in series for a, b in zip(errors, errors[1:], strict=False)]
    if not steps:
        return {"clicks": 0}
    rises = [s for s in steps if s[0] > 0]
    return {
        "clicks": len(steps),
        "worse": len(rises),
        "share_worse": round(len(rises) / len(steps), 3),
        "worst_rise": round(max((s[0] for s in rises), default=0.0), 5),
        "worst_rise_relative": round(max((s[1] for s in rises), default=0.0), 4),
        "mean_rise_when_worse": round(float(np.mean([s[0] for s in rises])), 5) if rises else 0.0,
    }


def summary(runs: list[dict], maps: tuple[str, ...]) -> dict:
    out = {}
    for m in maps:
        series = [r["errors"][m] for r in runs]
        out[m] = worsening(series) | {
            "mean_error_by_click": [round(float(np.mean(col)), 5) for col in _columns(series)],
        }
    return out


def _columns(series: list[list[float]]) -> list[list[float]]:
    longest = max(map(len, series), default=0)
    return [[s[i] for s in series if len(s) > i] for i in range(longest)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--curves", type=int, default=6, help="clicks per run (fewer where the truth cannot give them)")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--directions", nargs="+", choices=("source", "target"), default=["source", "target"])
    parser.add_argument("--max-vertices", type=int, default=20_000, help="skip pairs with a bigger mesh")
    parser.add_argument("--figures", action="store_true", help="record the intrinsic figures and sizes per click")
    parser.add_argument("--default-only", action="store_true", help="record the default and the 50 x 50 map only")
    add_pair_arguments(parser)
    parser.set_defaults(datasets=["faust", "cat-lion"])
    args = parser.parse_args()
    limit_blas_threads()
    runs = []
    data = shared_data()
    for pair in chosen_pairs(args):
        if max(load_mesh(data / path).n_vertices for path in (pair.source, pair.target)) > args.max_vertices:
            continue
        for direction in args.directions:
            loaded = loaded_pair(pair, direction)
            for seed in range(args.seeds):
                run = Run(loaded, seed, direction)
                runs.append(run_clicks(run, min(args.curves, run.max_curves()), args))
    print(
        json.dumps(
            {
                "benchmark": "monotone",
                "machine": machine(),
                "k": DEFAULT_K,
                "pairs": args.pairs,
                "error": "mean geodesic error / sqrt(area), rows not at a curve's end",
                "maps": "source -> target, converted as curvefm match hands them out (its orthogonal steps)",
                "summary": summary(runs, recorded_maps(args)),
                "runs": runs,
            }
        )
    )


if __name__ == "__main__":
    main()
