"""The paper's Figures 13/14: update time of the three solvers for the same energy, and time and accuracy
against the basis size k (the accuracy of the pointwise maps `curvefm match --k k` hands out, both directions).

An "update" is what happens when a user adds the n-th curve: the maps for n - 1 curves exist and the maps for
n curves are computed, both directions. Our solver solves exactly from scratch; conjugate gradients (the
paper's Algorithm 2) and L-BFGS start from the previous maps and stop at the same relative residual (1e-8).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from curvefm.evaluation.reproduce.datasets import Suite
from curvefm.evaluation.reproduce.scoring import LoadedPair
from curvefm.fmap import (
    DEFAULT_K,
    CurveMapSolver,
    FunctionalMaps,
    conjugate_gradient_solve,
    quasi_newton_solve,
    solve_both,
)
from curvefm.progress import Progress, no_progress
from curvefm.store import Store

Curves = Sequence[tuple[np.ndarray, np.ndarray]]
Timed = tuple[tuple[np.ndarray, np.ndarray], int]
"""What a timed solve returns: both maps and its iteration count."""

SLOW_SECONDS = 1.0  # a solver slower than this is timed once instead of `repeats` times


def run_timing(data: Path, suite: Suite, store: Store, progress: Progress = no_progress) -> dict[str, Any]:
    k_max = max(max(suite.timing_ks), DEFAULT_K)
    loaded = LoadedPair.load(data, suite.timing_pair, k_max, store)
    curves = loaded.pool.curves(max(max(suite.timing_counts), 10), seed=0, exact=False)
    with ThreadPoolExecutor(1, thread_name_prefix="curvefm-columns") as executor:  # where the reverse maps run
        by_count, by_k = _time_all(loaded, curves, suite, progress, executor)
    return {
        "pair": loaded.pair.name,
        "vertices": [mesh.n_vertices for mesh in loaded.shapes.meshes],
        "by_count": by_count,
        "by_k": by_k,
    }


def _time_all(
    loaded: LoadedPair, curves: Curves, suite: Suite, progress: Progress, executor: Executor
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    steps = len(suite.timing_counts) + len(suite.timing_ks)
    by_count = []
    for i, n in enumerate(suite.timing_counts):
        progress(i / steps, f"update time with {n} curves, k = {DEFAULT_K}")
        row = time_update(loaded, curves[:n], DEFAULT_K, suite.repeats, executor)
        by_count.append({"curves": n, "k": DEFAULT_K} | row)
    by_k = []
    for i, k in enumerate(suite.timing_ks):
        progress((len(suite.timing_counts) + i) / steps, f"time and accuracy at k = {k}")
        row = {"curves": 10, "k": k} | time_update(loaded, curves[:10], k, suite.repeats, executor)
        solver = build_solver(loaded, curves[:10], k, executor)
        fmaps = FunctionalMaps(solver.C_MN, solver.C_NM)
        errors = loaded.score_handed_out(fmaps, "source", 0, curves[:10], k=k)
        forward, back = errors["source_to_target"], errors["target_to_source"]
        by_k.append(row | {"mean": forward.mean, "mean_area": forward.mean_area, "mean_area_back": back.mean_area})
    progress(1.0, "timing done")
    return by_count, by_k


def build_solver(loaded: LoadedPair, curves: Curves, k: int, executor: Executor) -> CurveMapSolver:
    shapes = loaded.shapes
    solver = CurveMapSolver(
        shapes.mesh_M.vertices, shapes.basis_M, shapes.mesh_N.vertices, shapes.basis_N, k=k, executor=executor
    )
    if curves:
        solver.add_curves([(pm, pn, 1.0) for pm, pn in curves])
    return solver


def time_update(loaded: LoadedPair, curves: Curves, k: int, repeats: int, executor: Executor) -> dict[str, Any]:
    """Milliseconds (median) for our exact solve, warm-started CG and warm-started L-BFGS, both directions,
    with their iteration counts and their largest deviation from the exact maps (relative to max |C|)."""
    previous = build_solver(loaded, curves[:-1], k, executor)
    solver = build_solver(loaded, curves, k, executor)
    G_M, G_N, B = solver.normal_equations()
    lam_M, lam_N, alpha = solver.lam_M, solver.lam_N, solver.commutativity_weight
    exact = (solver.C_MN, solver.C_NM)

    def ours() -> Timed:
        C_MN, C_NM = solve_both(G_N, G_M, B, lam_N, lam_M, alpha, executor=executor)
        return (C_MN, C_NM), 0

    def iterative(solve: Callable[..., tuple[np.ndarray, int]]) -> Callable[[], Timed]:
        def run() -> Timed:
            C_MN, it_MN = solve(G_N, B, lam_N, lam_M, alpha, C0=previous.C_MN)
            C_NM, it_NM = solve(G_M, B.T, lam_M, lam_N, alpha, C0=previous.C_NM)
            return (C_MN, C_NM), it_MN + it_NM

        return run

    out = {}
    for name, run in (
        ("ours", ours),
        ("cg", iterative(conjugate_gradient_solve)),
        ("quasi_newton", iterative(quasi_newton_solve)),
    ):
        seconds, (maps, iterations) = _median_time(run, repeats)
        deviation = max(np.abs(m - e).max() / max(np.abs(e).max(), 1e-300) for m, e in zip(maps, exact, strict=True))
        out[name] = {"ms": 1e3 * seconds, "iterations": iterations, "deviation": float(deviation)}
    return out


def _median_time(run: Callable[[], Timed], repeats: int) -> tuple[float, Timed]:
    times: list[float] = []
    result: Any = None
    for _ in range(repeats):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
        if times[-1] > SLOW_SECONDS:
            break
    return statistics.median(times), result
