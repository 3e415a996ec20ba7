"""The per-column systems of one map update (curvefm.fmap.column_solve) on FAUST tr_reg_000 -> tr_reg_011.

For k = 30, 60, 120, 200, 1 / 5 / 10 geodesic curves (random vertex pairs; FAUST meshes share vertex ids, so
the same path on both) and alpha = 0.01, 0.1, 1, 100: median wall time of

* ``dposv_loop_ms``: the baseline, SciPy's f2py ``lapack.dposv`` once per column, one direction;
* ``ours_one_ms``: ``solve_columns`` (one direction, one thread);
* ``ours_both_ms``: ``solve_both`` (both directions, two threads);

each also as CPU time (``*_cpu_ms``), which a busy machine disturbs far less than wall time: with a free
second core ``ours_both_ms`` approaches ``ours_both_cpu_ms / 2``, without one it exceeds ``ours_both_cpu_ms``;

and the error of both maps against ``np.linalg.solve`` in float64 (max |C - C_ref| / max |C_ref|). Methods
are interleaved in every repetition. Budget (docs/performance.md): both directions at k = 120 in <= 10 ms.

Usage: ``python -m benchmarks.bench_column_solve [--repeat N] [--k 30 60 120 200]``; prints JSON. Bases are
cached in /tmp/curvefm-bench-columns (about 30 s each to compute the first time).
"""

import os

# Single-threaded BLAS unless the caller says otherwise: with OpenBLAS's own threads on a busy two-core
# machine, k >= 140 factorisations ran 10-60x slower (threads spinning for cores that are not free).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ThreadPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.linalg import lapack  # noqa: E402

from benchmarks.common import machine, shared_data  # noqa: E402
from curvefm.fmap import restrict, solve_both
from curvefm.fmap.column_solve import column_diagonals, solve_columns
from curvefm.geometry import load_mesh, shortest_path
from curvefm.registry import get  # noqa: E402
from curvefm.runtime import limit_blas_threads

CACHE = Path("/tmp/curvefm-bench-columns")
SAMPLES = 100
ALPHAS = (0.01, 0.1, 1.0, 100.0)
CURVES = (1, 5, 10)


def basis(mesh, name: str, k: int):
    path = CACHE / f"{name}-{mesh.content_hash}-{k}.npz"
    if path.exists():
        with np.load(path) as z:
            return z["evals"], z["evecs"]
    plugin = get("basis", "laplace-beltrami")
    b = plugin.run(mesh, k, plugin.parse_params({}))
    CACHE.mkdir(parents=True, exist_ok=True)
    np.savez(path, evals=b.evals, evecs=b.evecs)
    return b.evals, b.evecs


def problems(k_max: int):
    """Yield ``(n_curves, G_M, G_N, B, lam_M, lam_N)`` at k_max; smaller k are leading blocks of these."""
    M, N = (load_mesh(shared_data() / "faust" / f"{name}.off") for name in ("tr_reg_000", "tr_reg_011"))
    (evals_M, Phi), (evals_N, Psi) = basis(M, "tr_reg_000", k_max), basis(N, "tr_reg_011", k_max)
    rng = np.random.default_rng(0)
    sums = np.zeros((3, k_max, k_max))
    for n_curves in range(1, max(CURVES) + 1):
        a, b = rng.choice(M.n_vertices, 2, replace=False)
        path = shortest_path(M.edge_graph, a, b)
        phi, psi = restrict(M.vertices, path, Phi, SAMPLES), restrict(N.vertices, path, Psi, SAMPLES)
        sums += np.stack([phi.T @ phi, psi.T @ psi, psi.T @ phi]) / SAMPLES
        if n_curves in CURVES:
            yield (n_curves, *(sums / n_curves), evals_M, evals_N)


def dposv_loop(G, B, lam_rows, lam_cols, alpha):
    E = column_diagonals(G, lam_rows, lam_cols, alpha)
    C = np.empty_like(B)
    for j in range(B.shape[1]):
        A = G.copy()
        A.flat[:: len(G) + 1] += E[:, j]
        C[:, j] = lapack.dposv(A, B[:, j], lower=1)[1]
    return C


def reference(G, B, lam_rows, lam_cols, alpha):
    E = column_diagonals(G, lam_rows, lam_cols, alpha)
    A = np.repeat(G[None], B.shape[1], axis=0)
    A[:, np.arange(len(G)), np.arange(len(G))] += E.T
    return np.linalg.solve(A, B.T[:, :, None])[:, :, 0].T


def relative_error(C, C_ref):
    return float(np.abs(C - C_ref).max() / np.abs(C_ref).max())


def case(k, G_M, G_N, B, lam_M, lam_N, alpha, repeat, executor):
    methods = {
        "dposv_loop_ms": lambda: dposv_loop(G_N, B, lam_N, lam_M, alpha),
        "ours_one_ms": lambda: solve_columns(G_N, B, lam_N, lam_M, alpha),
        "ours_both_ms": lambda: solve_both(G_N, G_M, B, lam_N, lam_M, alpha, executor=executor),
    }
    wall = {name: [] for name in methods}
    cpu = {name: [] for name in methods}
    for _ in range(repeat):
        for name, fn in methods.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            fn()
            wall[name].append(1e3 * (time.perf_counter() - start))
            cpu[name].append(1e3 * (time.process_time() - start_cpu))
    C_MN, C_NM = solve_both(G_N, G_M, B, lam_N, lam_M, alpha)
    error = max(
        relative_error(C_MN, reference(G_N, B, lam_N, lam_M, alpha)),
        relative_error(C_NM, reference(G_M, B.T, lam_M, lam_N, alpha)),
    )
    E = column_diagonals(G_N, lam_N, lam_M, alpha)
    condition = max(
        float(ev[-1] / ev[0])
        for ev in (np.linalg.eigvalsh(G_N + np.diag(E[:, j])) for j in range(0, B.shape[1], max(1, k // 12)))
    )
    result = {name: round(statistics.median(times), 2) for name, times in wall.items()}
    result.update({name[:-3] + "_cpu_ms": round(statistics.median(times), 2) for name, times in cpu.items()})
    result["max_rel_error_vs_numpy"] = float(f"{error:.2e}")
    result["worst_condition_sampled"] = float(f"{condition:.2e}")
    return result


def all_cases(ks: list[int], repeat: int, executor) -> list[dict]:
    rows = []
    for n_curves, G_M, G_N, B, evals_M, evals_N in problems(max(ks)):
        for k in sorted(ks):
            scale = max(evals_M[k - 1], evals_N[k - 1])
            lam_M, lam_N = evals_M[:k] / scale, evals_N[:k] / scale
            blocks = [np.ascontiguousarray(X[:k, :k]) for X in (G_M, G_N, B)]
            for alpha in ALPHAS:
                row = {"k": k, "curves": n_curves, "alpha": alpha}
                row.update(case(k, *blocks, lam_M, lam_N, alpha, repeat, executor))
                rows.append(row)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=9)
    parser.add_argument("--k", type=int, nargs="+", default=[30, 60, 120, 200])
    args = parser.parse_args()
    load_start = os.getloadavg()
    with ThreadPoolExecutor(1) as executor:  # the second thread of ours_both
        rows = all_cases(args.k, args.repeat, executor)
    summary = {}
    for k in sorted(args.k):
        mine = [r for r in rows if r["k"] == k]
        summary[str(k)] = {
            "median_ours_both_ms": round(statistics.median(r["ours_both_ms"] for r in mine), 2),
            "median_ours_both_cpu_ms": round(statistics.median(r["ours_both_cpu_ms"] for r in mine), 2),
            "median_ours_one_ms": round(statistics.median(r["ours_one_ms"] for r in mine), 2),
            "median_ours_one_cpu_ms": round(statistics.median(r["ours_one_cpu_ms"] for r in mine), 2),
            "median_dposv_loop_one_ms": round(statistics.median(r["dposv_loop_ms"] for r in mine), 2),
            "median_dposv_loop_one_cpu_ms": round(statistics.median(r["dposv_loop_cpu_ms"] for r in mine), 2),
            "max_rel_error_vs_numpy": max(r["max_rel_error_vs_numpy"] for r in mine),
        }
    print(
        json.dumps(
            {
                "benchmark": "column_solve",
                "machine": machine(),
                "openblas_num_threads": os.environ.get("OPENBLAS_NUM_THREADS"),
                "loadavg_start_end": [round(load_start[0], 2), round(os.getloadavg()[0], 2)],
                "budget": "both directions at k = 120 in <= 10 ms",
                "summary": summary,
                "cases": rows,
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    limit_blas_threads()
    main()
