"""Solve the column-separable functional-map systems (DESIGN.md, "The mathematics in one screen").

Column ``j`` of ``C`` solves the SPD system

    (G + diag(E[:, j])) c_j = B[:, j],   E[i, j] = alpha * (lam_rows[i] - lam_cols[j])**2 + ridge.

All ``n`` systems share ``G`` and differ only in their diagonal. Factorising each one (LAPACK ``dposv`` per
column) costs ``n`` small factorisations that run far below matrix-product speed, so the main path is a
preconditioned conjugate-gradient iteration on all columns at once, where each step is one ``k x k`` product
with ``G`` and one with the preconditioner, and the preconditioner is exact for a few "anchor" columns:

- The columns are sorted by ``lam_cols`` and cut into groups of about :data:`GROUP_SIZE` neighbours. Each group
  uses the exact inverse of its middle column's matrix. Neighbouring columns' diagonals differ little, so
  the preconditioned spectra are narrow; CG needs fewer iterations the closer a column is to its anchor.
- A column stops when its relative residual ``||b - A c|| / ||b||`` falls below ``rtol`` (1e-12). The
  returned columns are then checked on the true residual, recomputed from scratch; every column that fails
  the check, broke down, or had not converged after :data:`MAX_ITER` steps (or once only a handful are left
  and a direct solve is cheaper than more steps) is solved directly with LAPACK ``dposv``. So the result
  satisfies the residual bound by construction, whatever the iteration did.

Why ``rtol`` is 1e-12 and not 1e-10: the systems built from real curves reach condition numbers of 1e7-1e8
(one curve, ``alpha = 0.01``); at a relative residual of 1e-10 the error in ``C`` was up to 1e-6 of
``max |C|``, at 1e-12 it stays below 1e-8 (see ``benchmarks/bench_column_solve.py``).

The ridge keeps every system positive definite when a column has no constraint in some direction, e.g. a
direction in the null space of ``G`` along which ``lam_rows[i] == lam_cols[j]``: see :func:`column_ridge`.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy.linalg import lapack

from curvefm.errors import CurvefmError

RIDGE = 1e-10  # relative to the mean diagonal of the systems, see column_ridge
RTOL = 1e-12
GROUP_SIZE = 15  # columns per anchor
MAX_ITER = 100
DIRECT_MAX_K = 48  # below this, n direct solves cost less than the anchors and iteration overhead
TAIL = 2  # when this few columns are still iterating, solve them directly

_pool: ThreadPoolExecutor | None = None


def column_ridge(G: np.ndarray, lam_rows: np.ndarray, lam_cols: np.ndarray, alpha: float) -> float:
    """The ridge added to every system: ``1e-10 * (trace(G) / k + alpha * mean((lam_rows_i - lam_cols_j)^2))``.

    That is 1e-10 of the mean diagonal entry over all ``k x n`` systems: invisible next to any entry that
    carries information (it shifts the solution by about 1e-10 relative where the system is well posed), yet
    it bounds the condition number of a singular system by about 1e10 so that it stays solvable in float64.
    """
    d2 = np.mean(np.subtract.outer(lam_rows, lam_cols) ** 2)
    return RIDGE * (float(np.trace(G)) / len(G) + alpha * float(d2))


def column_diagonals(G: np.ndarray, lam_rows: np.ndarray, lam_cols: np.ndarray, alpha: float) -> np.ndarray:
    """``E`` (k x n): column ``j`` of the result is the diagonal added to ``G`` in system ``j``."""
    E = np.subtract.outer(lam_rows, lam_cols)
    E *= E
    E *= alpha
    E += column_ridge(G, lam_rows, lam_cols, alpha)
    return E


def solve_columns(
    G: np.ndarray,
    B: np.ndarray,
    lam_rows: np.ndarray,
    lam_cols: np.ndarray,
    alpha: float,
    C0: np.ndarray | None = None,
    *,
    rtol: float = RTOL,
    stats: dict | None = None,
) -> np.ndarray:
    """``C`` (k x n) whose column ``j`` solves ``(G + diag(E[:, j])) c_j = B[:, j]`` (see the module doc).

    ``G`` (k x k) is symmetric positive semi-definite, ``B`` is k x n, ``lam_rows`` has k entries (the
    eigenvalues of the shape whose coefficients are the rows of ``C``), ``lam_cols`` has n. ``C0`` is an
    optional starting guess, e.g. the map before the last curve edit. Every column of the result has
    ``||B[:, j] - A_j C[:, j]|| <= rtol * ||B[:, j]||``. ``stats``, if given, receives ``iterations``,
    ``direct_columns`` and ``method``.
    """
    G, B, lam_rows, lam_cols = _checked(G, B, lam_rows, lam_cols, alpha)
    k, n = B.shape
    E = column_diagonals(G, lam_rows, lam_cols, alpha)
    info = {"iterations": 0, "direct_columns": n, "method": "direct"}
    if k <= DIRECT_MAX_K or n < 2 * GROUP_SIZE:
        C = _solve_direct(G, E, B, np.arange(n), np.empty_like(B))
    else:
        C = _solve_iterative(G, E, B, lam_cols, C0, rtol, info)
    if stats is not None:
        stats.update(info)
    return C


def solve_both(
    G_N: np.ndarray,
    G_M: np.ndarray,
    B: np.ndarray,
    lam_N: np.ndarray,
    lam_M: np.ndarray,
    alpha: float,
    C0_MN: np.ndarray | None = None,
    C0_NM: np.ndarray | None = None,
    *,
    rtol: float = RTOL,
) -> tuple[np.ndarray, np.ndarray]:
    """Both map directions at once: ``(C_MN, C_NM)``, the second direction in a worker thread.

    ``C_MN`` (k_N x k_M) takes coefficients on M to coefficients on N: ``G = G_N``, right-hand sides ``B``,
    rows ``lam_N``, columns ``lam_M``. ``C_NM`` (k_M x k_N) is the reverse: ``G_M``, ``B.T``, rows ``lam_M``,
    columns ``lam_N``. The matrix products and element-wise steps release the GIL, so the two overlap.
    """
    global _pool
    if _pool is None:
        _pool = ThreadPoolExecutor(1, thread_name_prefix="curvefm-columns")
    B = np.asarray(B, dtype=np.float64)
    reverse = _pool.submit(solve_columns, G_M, B.T, lam_M, lam_N, alpha, C0_NM, rtol=rtol)
    C_MN = solve_columns(G_N, B, lam_N, lam_M, alpha, C0_MN, rtol=rtol)
    return C_MN, reverse.result()


def _checked(G, B, lam_rows, lam_cols, alpha):
    G = np.asarray(G, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    lam_rows = np.asarray(lam_rows, dtype=np.float64).ravel()
    lam_cols = np.asarray(lam_cols, dtype=np.float64).ravel()
    k = len(lam_rows)
    if G.shape != (k, k) or B.shape != (k, len(lam_cols)):
        raise CurvefmError(
            f"column solve: G is {G.shape}, B is {B.shape}, {k} row eigenvalues and {len(lam_cols)} column "
            f"eigenvalues; expected G (k x k), B (k x n), k and n eigenvalues"
        )
    if not alpha >= 0:
        raise CurvefmError(f"column solve: alpha must be >= 0, got {alpha}")
    return G, B, lam_rows, lam_cols


def _solve_direct(G: np.ndarray, E: np.ndarray, B: np.ndarray, cols: np.ndarray, out: np.ndarray) -> np.ndarray:
    """One LAPACK ``dposv`` per column in ``cols``, written into ``out``."""
    diag = np.arange(len(G)) * (len(G) + 1)
    for j in cols:
        A = G.copy()
        A.flat[diag] += E[:, j]
        _, x, info = lapack.dposv(A, B[:, j], lower=1)
        if info != 0:
            raise CurvefmError(f"column solve: system {j} is not positive definite (is G symmetric PSD?)")
        out[:, j] = x
    return out


def _anchor_inverses(G: np.ndarray, E: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Exact inverses of the systems of the middle column of each group, stacked (groups x k x k)."""
    k = len(G)
    diag = np.arange(k) * (k + 1)
    invs = np.empty((len(bounds) - 1, k, k))
    for g in range(len(bounds) - 1):
        A = G.copy()
        A.flat[diag] += E[:, (bounds[g] + bounds[g + 1]) // 2]
        c, info = lapack.dpotrf(A, lower=1, overwrite_a=1)
        if info == 0:
            invs[g], info = lapack.dpotri(c, lower=1, overwrite_c=1)
        if info != 0:
            raise CurvefmError("column solve: a system is not positive definite (is G symmetric PSD?)")
    lower = np.tri(k, dtype=bool)  # dpotri fills the lower triangle only
    return np.where(lower, invs, invs.transpose(0, 2, 1))


def _solve_iterative(G, E, B, lam_cols, C0, rtol, info) -> np.ndarray:
    k, n = B.shape
    order = np.argsort(lam_cols, kind="stable")
    E, Bs = E[:, order], B[:, order]
    n_groups = max(1, round(n / GROUP_SIZE))
    bounds = np.linspace(0, n, n_groups + 1).round().astype(int)
    group = np.repeat(np.arange(n_groups), np.diff(bounds))
    invs = _anchor_inverses(G, E, bounds)

    X = np.zeros((k, n)) if C0 is None else np.array(C0, dtype=np.float64)[:, order]
    target = rtol**2 * np.einsum("ij,ij->j", Bs, Bs)
    R = Bs - G @ X - E * X if C0 is not None else Bs.copy()
    act = np.flatnonzero(np.einsum("ij,ij->j", R, R) > target)
    failed: list[np.ndarray] = []
    it = 0
    if len(act) > TAIL:
        it, act, bad = _pcg(G, E, X, R, act, target, group, invs)
        failed.append(bad)

    # Verify every column on its true residual; whatever fails (or never converged) is solved directly.
    R = Bs - G @ X - E * X
    unsure = np.einsum("ij,ij->j", R, R) > 4 * target
    unsure[act] = True
    for bad in failed:
        unsure[bad] = True
    direct = np.flatnonzero(unsure)
    _solve_direct(G, E, Bs, direct, X)
    info.update(iterations=it, direct_columns=len(direct), method="pcg-anchors")
    C = np.empty_like(X)
    C[:, order] = X
    return C


def _pcg(G, E, X, R, act, target, group, invs):
    """Batched preconditioned CG on the columns ``act`` of ``X`` (updated in place).

    Columns live compacted (only the active ones, in group order) and leave the working set once converged;
    compaction copies every working array, so converged columns are first frozen (zero step) and only swept
    out once enough of them have accumulated. Returns (iterations, still active columns, broken-down ones).
    """
    n_groups = len(invs)

    def precondition(Rw, gw):
        Z = np.empty_like(Rw)
        cuts = np.searchsorted(gw, np.arange(n_groups + 1))
        for g in range(n_groups):
            if cuts[g + 1] > cuts[g]:
                np.matmul(invs[g], Rw[:, cuts[g] : cuts[g + 1]], out=Z[:, cuts[g] : cuts[g + 1]])
        return Z

    Xw, Rw, Ew, tw, gw = X[:, act], R[:, act], E[:, act], target[act], group[act]
    Z = precondition(Rw, gw)
    P = Z
    rz = np.einsum("ij,ij->j", Rw, Z)
    frozen = np.zeros(len(act), dtype=bool)
    broken: list[np.ndarray] = []
    AP, tmp = np.empty_like(P), np.empty_like(P)
    it = 0
    while it < MAX_ITER:
        it += 1
        np.matmul(G, P, out=AP)
        np.multiply(Ew, P, out=tmp)
        AP += tmp
        pap = np.einsum("ij,ij->j", P, AP)
        ok = (pap > 0) & ~frozen  # pap <= 0 only by rounding on a nearly singular column: solve it directly
        step = np.divide(rz, pap, out=np.zeros_like(rz), where=ok)
        np.multiply(P, step, out=tmp)
        Xw += tmp
        np.multiply(AP, step, out=tmp)
        Rw -= tmp
        converged = np.einsum("ij,ij->j", Rw, Rw) <= tw
        broken.append(act[~ok & ~frozen])
        frozen |= converged | ~ok
        n_left = len(act) - int(frozen.sum())
        if n_left <= TAIL or frozen.sum() >= max(4, len(act) // 8):
            X[:, act[frozen]] = Xw[:, frozen]
            keep = ~frozen
            act, Xw, Rw, Ew, tw, gw, rz, P = (a[..., keep] for a in (act, Xw, Rw, Ew, tw, gw, rz, P))
            frozen = frozen[keep]
            AP, tmp = np.empty_like(P), np.empty_like(P)
            if n_left <= TAIL:
                break
        Z = precondition(Rw, gw)
        rz_new = np.einsum("ij,ij->j", Rw, Z)
        P *= np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz != 0)
        P += Z
        rz = rz_new
    X[:, act] = Xw
    return it, act[~frozen], np.concatenate(broken)
