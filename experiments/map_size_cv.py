"""Can the user's own curves choose the size the combined map is handed out at, by cross-validation?

On ``curvefm reproduce``'s full suite (its pairs, ``CurvePool`` traced curves, seeds and scorer; counts a pair's
pool cannot draw are skipped, as the report skips them), per run: the mean error by geodesic diameter (the reproduce
report's figure) of the default ``combined`` method, of the combined map solved at k = 120 and handed out at each
fixed size s x s, and held-out errors per size from K-fold cross-validation on the run's curves. A fold solves the
combined energy without its held-out curves (their products subtracted from the sums, the landmark prior from all
endpoints reused, so one solve per direction and fold gives every size as a truncation ``C[:s, :s]``), carries the
held-out source curves' samples to the target by nearest neighbours in the spectral embedding (the conversion the
scorer uses, restricted to the samples as queries) and measures, by sqrt(area) of the target, how far each lands
from the held-out target curve: from the target curve's sample at the same arc-length fraction (``at_t``) or from
the nearest vertex of the target curve (``to_curve``). ``NM`` carries M's samples with ``C_NM`` (what the scorer
reads), ``MN`` N's samples with ``C_MN``. The summary chooses a size per run by several rules (the lowest held-out
error, ties to the larger size) and reports per cell the error of the chosen maps. Prints one JSON object.
experiments/map_size_cv.json is its output with the shared prior (``--folds 4 10 0``) and
experiments/map_size_cv_honest.json with a prior per fold (``--folds 4 10 --honest-prior``), 2026-11-23
(deterministic, so the busy machine does not matter).

Result, not adopted: the held-out curves do not tell the sizes apart. The default (50 x 50 below 20 curves, 120 x
120 from 20) is at least as good as the best baseline in 9 of these 10 cells (all but cat -> lion with 20 curves:
0.0218 vs NO17's 0.0204); every cross-validated choice (4 or 10 folds or one curve out, either measure, either
direction or both, shared or per-fold prior, even with a 1-8% margin towards the larger size, chosen afterwards) in
at most 7. The planned rule (4 folds, ``NM``, ``at_t``, shared prior) takes cat -> lion with 20 curves to 0.0210
(sizes 90 / 50 / 70), not below NO17, and costs FAUST with 20 curves 0.0100 -> 0.0109, TOSCA 0.0114 -> 0.0133 and
TOSCA across classes 0.0227 -> 0.0237; with 10 curves it gains on FAUST (0.0136 -> 0.0126) and loses on the other
four datasets. The only choices that take cat -> lion below NO17 (``MN``, ``to_curve``: 50 in all three runs,
0.0202) pick 50 on most runs of FAUST-5k and TOSCA across classes too (20 curves: 0.0171, 0.0260). Per run, the
held-out error's ranking of the four sizes agrees with the true error's only weakly (mean Spearman 0.0-0.2) and
picks the run's best size in 13-31 of 66 runs (chance: 16.5). The shared prior has seen the held-out curves' ends
and favours 50 x 50; a prior per fold removes that (FAUST 20: 0.0103, TOSCA 20: 0.0122) but not the noise, and costs
3-5 s per run with 4 folds. Likely reasons (not measured): held-out curves join the same landmark candidates the
prior and the kernel maps use, so their samples are the points every size maps well; traced geodesics on a
non-isometric pair do not correspond point by point; and the sizes differ in detail that a few hundred curve samples
hardly probe. Cost in any case: 0.2-2 s per run with 4 folds, of which the landing test (a spectral embedding of the
whole target per size, nearest neighbours of the samples) is about 0.4 s at FAUST's size, far above a session edit's
30 ms.

    nice python -m experiments.map_size_cv [--counts 10 20] [--sizes 50 70 90 120] [--folds 4 10 0]
                                                [--honest-prior]

``--folds 0`` is leave-one-curve-out.
"""

import argparse
import json
import math
import time
from collections import defaultdict

import numpy as np

from benchmarks.common import machine, shared_data
from curvefm import registry
from curvefm.errors import CurvefmError
from curvefm.evaluation.reproduce.datasets import FULL_PAIRS
from curvefm.evaluation.reproduce.scoring import LoadedPair
from curvefm.fmap import DEFAULT_K, CombinedMapSolver, FunctionalMaps, Hints, curves_alone_suffice, restrict
from curvefm.fmap.column_solve import Prior, solve_columns
from curvefm.fmap.combined import ONE_CURVE_PRIOR_FACTOR
from curvefm.fmap.landmark_prior import landmark_maps
from curvefm.fmap.maps import curve_endpoints
from curvefm.pointwise import nearest_neighbors
from curvefm.progress import no_progress
from curvefm.runtime import limit_blas_threads
from curvefm.store import Store

SEEDS = 3
STRIDE = 4  # every 4th of a curve's 100 samples is a held-out query
MEASURES = ("at_t", "to_curve")
DIRECTIONS = ("NM", "MN")


def held_out_errors(
    solver: CombinedMapSolver, areas: tuple[float, float], sizes, folds: int, honest: bool = False
) -> tuple[dict, float]:
    """``{(direction, measure): (len(sizes),) mean held-out error}`` and the seconds it took (the all-curves prior
    excluded). Curve i is held out in fold ``i % folds`` (``folds`` 0: one fold per curve). ``honest``: each fold
    gets its own prior, from its kept curves' endpoints, instead of reusing the prior from every endpoint (whose
    50 x 50 block has seen the held-out curves' ends)."""
    solver.settle()  # the prior from all endpoints
    started = time.perf_counter()
    terms = list(solver.curves.values())
    folds = len(terms) if folds <= 0 else min(folds, len(terms))
    products = [term.weight * solver._products(term) for term in terms]
    total = sum(products)
    prior = solver._prior[1] if solver._prior is not None else None
    sums = {(d, m): np.zeros(len(sizes)) for d in DIRECTIONS for m in MEASURES}
    queries = 0
    for fold in range(folds):
        held = [term for i, term in enumerate(terms) if i % folds == fold]
        kept = [term for i, term in enumerate(terms) if i % folds != fold]
        sums_kept = total - sum(p for i, p in enumerate(products) if i % folds == fold)
        if honest:
            prior = fold_prior(solver, kept)
        for direction, C in fold_maps(solver, sums_kept / sum(t.weight for t in kept), len(kept), prior).items():
            for measure, errors in landing_errors(solver, direction, C, held, sizes, areas).items():
                sums[(direction, measure)] += errors.sum(axis=1)
        queries += sum(len(range(0, solver.samples, STRIDE)) for _ in held)
    return {key: value / queries for key, value in sums.items()}, time.perf_counter() - started


def fold_prior(solver: CombinedMapSolver, kept) -> FunctionalMaps | None:
    """NO17's maps from the kept curves' endpoints, as the solver would compute them for those curves alone."""
    ends = curve_endpoints([(term.path_M, term.path_N) for term in kept])
    try:
        return landmark_maps(solver.basis_M, solver.basis_N, np.array(sorted(map(tuple, ends.tolist()))))
    except CurvefmError:
        return None


def fold_maps(solver: CombinedMapSolver, sums: np.ndarray, kept: int, prior: FunctionalMaps | None) -> dict:
    """Both k x k maps of the combined energy for normalised curve ``sums`` (3 x k x k) of ``kept`` curves, with the
    landmark ``prior`` weighted as :class:`CombinedMapSolver` weighs it."""
    G_M, G_N, B = sums + solver._signatures
    prior_NM = prior_MN = None
    if prior is not None and solver.prior_weight > 0:
        weight = solver.prior_weight * (ONE_CURVE_PRIOR_FACTOR if kept == 1 else 1.0)
        weight *= float(np.trace(G_M) + np.trace(G_N)) / (2 * solver.k)
        prior_NM, prior_MN = Prior(prior.C_NM, weight), Prior(prior.C_MN, weight)
    return {
        "NM": solve_columns(G_M, B.T, solver.lam_M, solver.lam_N, solver.alpha, prior=prior_NM),
        "MN": solve_columns(G_N, B, solver.lam_N, solver.lam_M, solver.alpha, prior=prior_MN),
    }


def landing_errors(solver: CombinedMapSolver, direction: str, C: np.ndarray, held, sizes, areas) -> dict:
    """``{measure: (len(sizes), queries) distances}``: where the held-out curves' source samples land on the target
    through ``C[:s, :s]`` (``NM``: M's samples through ``C_NM``; ``MN``: N's through ``C_MN``), by sqrt(area)."""
    sides = {"M": (solver.vertices_M, solver.basis_M), "N": (solver.vertices_N, solver.basis_N)}
    source, target = ("M", "N") if direction == "NM" else ("N", "M")
    (vertices_s, basis_s), (vertices_t, basis_t) = sides[source], sides[target]
    scale = np.sqrt(areas[1] if target == "N" else areas[0])
    paths = [(t.path_M, t.path_N) if source == "M" else (t.path_N, t.path_M) for t in held]
    queries = np.vstack([restrict(vertices_s, p_s, basis_s.evecs, solver.samples)[::STRIDE] for p_s, _ in paths])
    at = np.vstack([restrict(vertices_t, p_t, vertices_t, solver.samples)[::STRIDE] for _, p_t in paths])
    curve = np.concatenate([np.full(len(range(0, solver.samples, STRIDE)), i) for i in range(len(paths))])
    out = {"at_t": np.zeros((len(sizes), len(queries))), "to_curve": np.zeros((len(sizes), len(queries)))}
    for j, size in enumerate(sizes):
        embedded = basis_t.evecs[:, :size] @ C[:size, :size].T
        images = vertices_t[nearest_neighbors(embedded, queries[:, :size], "exact")]
        out["at_t"][j] = np.linalg.norm(images - at, axis=1) / scale
        for i, (_, p_t) in enumerate(paths):
            mine = curve == i
            gaps = np.linalg.norm(images[mine, None, :] - vertices_t[p_t][None], axis=2)
            out["to_curve"][j, mine] = gaps.min(axis=1) / scale
    return out


def run(loaded: LoadedPair, count: int, seed: int, sizes, fold_counts, honest: bool) -> dict:
    shapes = loaded.shapes
    curves = loaded.pool.curves(count, seed, False)
    hints = Hints.from_curves(curves)
    row = {"dataset": loaded.pair.dataset, "pair": loaded.pair.name, "curves": count, "seed": seed}
    plugin, params = registry.load("method", "combined", {})
    default = plugin.run(shapes, hints, params, no_progress)
    row["default"] = loaded.score(default.C_NM, seed, curves).mean
    row["default_size"] = int(default.C_NM.shape[0])
    row["curves_alone"] = bool(curves_alone_suffice(shapes.basis_M, shapes.basis_N, curves))
    energy = params.solver_params() | {"full_size_curves": 1, "non_isometric_spectra": math.inf}  # as solved
    k = min(shapes.basis_M.k, shapes.basis_N.k)
    with CombinedMapSolver(
        shapes.mesh_M.vertices, shapes.basis_M, shapes.mesh_N.vertices, shapes.basis_N, k=k, **energy
    ) as solver:
        solver.add_curves([(pm, pn, 1.0) for pm, pn in curves])
        C_NM = solver.C_NM
        row["fixed"] = {str(s): loaded.score(C_NM[:s, :s], seed, curves).mean for s in sizes}
        row["cv"] = {}
        for folds in fold_counts:
            areas = (shapes.mesh_M.area, shapes.mesh_N.area)
            errors, seconds = held_out_errors(solver, areas, sizes, folds, honest)
            row["cv"][str(folds)] = {"seconds": round(seconds, 3)} | {
                f"{d}_{m}": [round(float(e), 6) for e in errors[(d, m)]] for d, m in errors
            }
    return row


def choose(errors: list[float], sizes, tolerance: float = 0.0) -> int:
    """The largest size whose error is within ``tolerance`` (relative) of the lowest."""
    best = min(errors)
    return max(s for s, e in zip(sizes, errors, strict=True) if e <= best * (1 + tolerance))


def summary(rows: list[dict], sizes, fold_counts) -> list[dict]:
    rules = {}
    for folds in fold_counts:
        for measure in MEASURES:
            for directions in (("NM",), ("MN",), ("NM", "MN")):
                rules[f"K{folds}_{'+'.join(directions)}_{measure}"] = (str(folds), directions, measure)
    groups = defaultdict(list)
    for row in rows:
        groups[(row["dataset"], row["curves"])].append(row)
    out = []
    for (dataset, count), group in groups.items():
        fixed = {str(s): round(float(np.mean([r["fixed"][str(s)] for r in group])), 5) for s in sizes}
        default = round(float(np.mean([r["default"] for r in group])), 5)
        cell = {"dataset": dataset, "curves": count, "runs": len(group), "default": default, "fixed": fixed}
        cell["rules"] = {}
        for name, (folds, directions, measure) in rules.items():
            errs, chosen = [], []
            for r in group:
                if r["curves_alone"]:  # the method solves with the curve energy: nothing to choose
                    errs.append(r["default"])
                    chosen.append(None)
                    continue
                cv = np.sum([r["cv"][folds][f"{d}_{measure}"] for d in directions], axis=0)
                size = choose(list(cv), sizes)
                errs.append(r["fixed"][str(size)])
                chosen.append(size)
            cell["rules"][name] = {"mean": round(float(np.mean(errs)), 5), "chosen": chosen}
        out.append(cell)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[10, 20])
    parser.add_argument("--sizes", type=int, nargs="+", default=[50, 70, 90, 120])
    parser.add_argument("--folds", type=int, nargs="+", default=[4, 10, 0])
    parser.add_argument("--honest-prior", action="store_true", help="a prior per fold from its kept curves' ends")
    parser.add_argument("--pairs", type=int, nargs="+", default=None, help="indices into the full suite's pairs")
    args = parser.parse_args()
    limit_blas_threads()
    data, store = shared_data(), Store()
    rows = []
    pairs = FULL_PAIRS if args.pairs is None else [FULL_PAIRS[i] for i in args.pairs]
    for pair in pairs:
        loaded = LoadedPair.load(data, pair, DEFAULT_K, store)
        for count in (c for c in args.counts if c <= loaded.pool.max_curves):
            for seed in range(SEEDS):
                rows.append(run(loaded, count, seed, args.sizes, args.folds, args.honest_prior))
                print(json.dumps(rows[-1]), file=__import__("sys").stderr, flush=True)
    print(
        json.dumps(
            {
                "benchmark": "map_size_cv",
                "machine": machine(),
                "k": DEFAULT_K,
                "seeds": SEEDS,
                "honest_prior": args.honest_prior,
                "sizes": args.sizes,
                "cells": summary(rows, args.sizes, args.folds),
                "rows": rows,
            }
        )
    )


if __name__ == "__main__":
    main()
