"""The column-separable functional-map systems (docs/concepts.md, "Solving").

Column ``j`` of ``C`` solves the symmetric positive definite system

    (G + diag(E[:, j])) c_j = B[:, j],   E[i, j] = alpha * (lam_rows[i] - lam_cols[j])**2 + ridge,

one Cholesky factorisation per column (LAPACK ``dposv``): exact, and backward stable however badly
conditioned the system (systems built from one real curve reach condition numbers of 1e7-1e8).

Why not something cleverer. The ``n`` systems share ``G``, but their diagonals span the three-dimensional space
of ``Lambda^2``, ``Lambda`` and ``I`` (a quadratic family in ``lam_cols[j]``), so no single factorisation or
eigendecomposition of ``k x k`` matrices serves them all; the ``2k`` linearisation ``(T - mu I) z = f`` does,
but its Hessenberg or Schur form alone costs more than all ``n`` Cholesky factorisations at ``k = 120``.
Batched preconditioned CG on all columns at once (each step one product with ``G`` and one with the exact
inverse of an "anchor" column's matrix, one anchor per 15 columns) needs 10-80 steps to reach a relative
residual of 1e-12, which is what an error below 1e-8 of ``max |C|`` takes on systems from real curves; at
``k = 120`` it ran at 0.5-1.4x the speed of this loop (0.5-0.8x at ``alpha`` = 10-100), so it was dropped.

The floor (2026-11-28, AMD EPYC, 2 cores, loaded). An edit's update at k = 120 spends about 90% of its CPU time in
these 2k factorisations (both directions); restricting the curve and summing its products take 0.2-0.3 ms. One
``dposv`` of a 120 x 120 system takes 34-37 us (about 17 GFlop/s, a third of what ``dgemm`` reaches at that size),
so the 240 factorisations cost 8.1-8.5 ms of CPU time, 4.2 ms at best on two idle cores. The paper's CG, warm-started,
needs 557-583 iterations (both directions), one k x k product each: 55-60 ms of CPU time. Per-column factorisations
therefore cannot make the update more than about 14x faster than this CG on two cores (``speedup_bound_two_cores`` in
benchmarks/bench_curve_update.py).
What else was tried: a low-rank update of the factors when a curve is added does not exist, because the curve weights
are normalised by their sum (every edit rescales all curve terms against the commutativity diagonal, a full-rank
change) and one curve's term has rank 100 (its samples) of 120; NumPy's batched ``cholesky`` (one GIL-free call per
direction) ran at half the speed of this loop; blocked factorisations from ``dpotrf``/``dtrsm``/``dsyrk`` through the
same pointers were 1.5x slower (call overheads at this size); systems assembled in chunks of 8 and shared between the
two threads through one queue changed nothing measurable (load 14-21); OpenBLAS's other kernels
(``OPENBLAS_CORETYPE``) neither. The 2k linearisation above: 3.4 ms per direction for its Hessenberg form (before the
k shifted solves), 17 ms for its Schur form.

Why ctypes. SciPy's f2py wrappers of ``dposv``/``dpotrf`` hold the GIL, so the two map directions could not
run side by side on two cores. ``scipy.linalg.cython_lapack`` exports the same LAPACK functions as C function
pointers; a call through ``ctypes`` releases the GIL, and it also skips the wrappers' argument copies. If the
pointer cannot be had (another Python, a SciPy whose LAPACK takes 64-bit integers) the f2py wrapper is used.

Run with single-threaded BLAS (``OPENBLAS_NUM_THREADS=1``): at these sizes OpenBLAS's own threads cannot help,
and on a busy two-core machine they made factorisations of k >= 140 run 10-60 times slower.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack

from curvefm.errors import InternalError, InvalidInput

RIDGE = 1e-10  # relative to the mean diagonal of the systems, see column_ridge
PARALLEL_MIN_SIZE = 40 * 40  # smaller maps take under a millisecond: handing half to a thread costs more


def _gil_free_dposv() -> Callable[..., None] | None:
    """``dposv`` from ``scipy.linalg.cython_lapack`` as a ctypes function (8 pointer arguments), or None."""
    try:
        from scipy.linalg import cython_lapack

        capsule = cython_lapack.__pyx_capi__["dposv"]
        api = ctypes.pythonapi  # own prototypes, so that ctypes.pythonapi's shared ones stay untouched
        get_name = ctypes.PYFUNCTYPE(ctypes.c_char_p, ctypes.py_object)(("PyCapsule_GetName", api))
        get_pointer = ctypes.PYFUNCTYPE(ctypes.c_void_p, ctypes.py_object, ctypes.c_char_p)(
            ("PyCapsule_GetPointer", api)
        )
        name = get_name(capsule)
        # the integers must be C ints: (uplo, n, nrhs, a, lda, b, ldb, info)
        if name.count(b"int *") != 5 or b"long" in name:
            return None
        return ctypes.CFUNCTYPE(None, *[ctypes.c_void_p] * 8)(get_pointer(capsule, name))
    except (ImportError, AttributeError, KeyError, ValueError, TypeError):
        return None


_DPOSV = _gil_free_dposv()


@dataclass(frozen=True)
class Prior:
    """A map the solution is pulled towards on its leading block: ``weight ||C[:p, :q] - C0||^2``."""

    C0: np.ndarray
    weight: float


def parallel_pays_off(size: int) -> bool:
    """Whether splitting systems with ``size`` right-hand-side entries over two threads is faster: the systems
    are large enough and the GIL-free ``dposv`` is available (the f2py fallback holds the GIL)."""
    return _DPOSV is not None and size >= PARALLEL_MIN_SIZE


def column_ridge(G: np.ndarray, lam_rows: np.ndarray, lam_cols: np.ndarray, alpha: float) -> float:
    """The ridge added to every system: ``1e-10 * (trace(G) / k + alpha * mean((lam_rows_i - lam_cols_j)^2))``.

    That is 1e-10 of the mean diagonal entry over all ``k x n`` systems. It keeps a system positive definite
    when a direction carries no information at all (in the null space of ``G`` and with
    ``lam_rows[i] == lam_cols[j]``), bounding its condition number by about 1e11 so that Cholesky still
    succeeds in float64, while it moves any well-determined solution by only about 1e-10 relative.
    """
    scale = float(np.trace(G)) / len(G) + alpha * float(np.mean(np.subtract.outer(lam_rows, lam_cols) ** 2))
    return RIDGE * (scale if scale > 0 else 1.0)


def column_diagonals(G: np.ndarray, lam_rows: np.ndarray, lam_cols: np.ndarray, alpha: float) -> np.ndarray:
    """``E`` (k x n): column ``j`` is the diagonal added to ``G`` in system ``j``, ridge included."""
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
    *,
    prior: Prior | None = None,
    executor: Executor | None = None,
) -> np.ndarray:
    """``C`` (k x n) whose column ``j`` solves ``(G + diag(E[:, j])) c_j = B[:, j]`` (see the module doc).

    ``G`` (k x k) is symmetric positive semi-definite (one triangle is read), ``B`` is k x n, ``lam_rows``
    has k entries (eigenvalues of the shape whose coefficients are the rows of ``C``) and ``lam_cols`` n.
    A ``prior`` adds ``weight ||C[:p, :q] - C0||^2`` for its ``C0`` (p x q) to the energy: ``weight`` on the
    first p diagonal entries of the first q systems and ``weight C0`` to their right-hand sides, so the
    systems keep their form. With an ``executor``, half of the columns are solved on it while the calling
    thread solves the other half.
    """
    G, B, lam_rows, lam_cols = _checked(G, B, lam_rows, lam_cols, alpha)
    if B.size == 0:
        return np.zeros(B.shape)
    ET = np.ascontiguousarray(column_diagonals(G, lam_rows, lam_cols, alpha).T)
    BT = np.array(B.T, order="C")  # a copy: B.T may be the caller's array, which the prior must not change
    if prior is not None:
        p, q = prior.C0.shape
        ET[:q, :p] += prior.weight
        BT[:q, :p] += prior.weight * prior.C0.T
    CT = np.empty_like(BT)
    n = len(BT)
    if executor is not None and parallel_pays_off(B.size):
        half = n // 2
        other = executor.submit(_solve_rows, G, ET, BT, CT, range(half, n))
        _solve_rows(G, ET, BT, CT, range(half))
        other.result()
    else:
        _solve_rows(G, ET, BT, CT, range(n))
    return CT.T.copy()


def solve_both(
    G_N: np.ndarray,
    G_M: np.ndarray,
    B: np.ndarray,
    lam_N: np.ndarray,
    lam_M: np.ndarray,
    alpha: float,
    *,
    priors: tuple[Prior | None, Prior | None] | None = None,
    executor: Executor | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Both map directions: ``(C_MN, C_NM)``, with optional ``priors`` for them (in that order). With an
    ``executor`` the reverse map is solved on it, side by side with ``C_MN`` on the calling thread; without,
    one after the other.

    ``C_MN`` (k_N x k_M) takes coefficients on M to coefficients on N: ``G = G_N``, right-hand sides ``B``
    (k_N x k_M), rows ``lam_N``, columns ``lam_M``. ``C_NM`` (k_M x k_N) is the reverse map: ``G = G_M``,
    right-hand sides ``B.T``, rows ``lam_M``, columns ``lam_N``.
    """
    B = np.asarray(B, dtype=np.float64)
    prior_MN, prior_NM = priors or (None, None)
    if executor is None or not parallel_pays_off(B.size):
        return (
            solve_columns(G_N, B, lam_N, lam_M, alpha, prior=prior_MN),
            solve_columns(G_M, B.T, lam_M, lam_N, alpha, prior=prior_NM),
        )
    reverse = executor.submit(solve_columns, G_M, B.T, lam_M, lam_N, alpha, prior=prior_NM)
    C_MN = solve_columns(G_N, B, lam_N, lam_M, alpha, prior=prior_MN)
    return C_MN, reverse.result()


def _checked(
    G: np.ndarray, B: np.ndarray, lam_rows: np.ndarray, lam_cols: np.ndarray, alpha: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    G = np.ascontiguousarray(G, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    lam_rows = np.asarray(lam_rows, dtype=np.float64).ravel()
    lam_cols = np.asarray(lam_cols, dtype=np.float64).ravel()
    k = len(lam_rows)
    if G.shape != (k, k) or B.shape != (k, len(lam_cols)):
        raise InvalidInput(
            f"column solve: G is {G.shape}, B is {B.shape}, with {k} row and {len(lam_cols)} column "
            "eigenvalues; expected G (k x k) and B (k x n) for k row and n column eigenvalues"
        )
    if not (np.isfinite(alpha) and alpha >= 0):
        raise InvalidInput(f"column solve: alpha must be a finite number >= 0, got {alpha}")
    for name, array in (("G", G), ("B", B), ("row eigenvalues", lam_rows), ("column eigenvalues", lam_cols)):
        if not np.isfinite(array).all():
            raise InvalidInput(f"column solve: {name} must be finite (found NaN or infinity)")
    return G, B, lam_rows, lam_cols


def _solve_rows(G: np.ndarray, ET: np.ndarray, BT: np.ndarray, CT: np.ndarray, rows: range) -> None:
    """Solve the systems ``rows`` (rows of ``ET``, ``BT``) into the same rows of ``CT``."""
    k = len(G)
    if _DPOSV is None:
        for j in rows:
            A = G.copy()
            A.flat[:: k + 1] += ET[j]
            _, x, info = lapack.dposv(A, BT[j], lower=1)
            _raise_if_failed(info, j)
            CT[j] = x
        return
    a = np.empty((k, k), order="F")  # overwritten by the factor in every call
    x = np.empty(k)  # right-hand side in, solution out
    diagonal = a.reshape(-1, order="F")[:: k + 1]  # a view
    ints = np.array([k, 1, 0], dtype=np.intc)  # n (also lda, ldb), nrhs, info
    p = ints.ctypes.data
    size = ints.itemsize
    args = (b"L", p, p + size, a.ctypes.data, p, x.ctypes.data, p, p + 2 * size)
    Gt = G.T  # G is symmetric, and G.T has the Fortran layout of `a`: a plain memory copy
    for j in rows:
        np.copyto(a, Gt)
        diagonal += ET[j]
        x[:] = BT[j]
        _DPOSV(*args)
        _raise_if_failed(int(ints[2]), j)
        CT[j] = x


def solve_spd(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``x`` with ``A x = b`` for a symmetric positive definite ``A`` (one triangle is read; ``A`` is overwritten
    by its factor when it is a C- or Fortran-contiguous float64 array). Through the GIL-free ``dposv`` where
    available: a background thread's large solve (NO17's 2500 x 2500 system at k = 50, 0.2 s) then leaves the
    interpreter to the requests being answered meanwhile. Raises ``numpy.linalg.LinAlgError`` when ``A`` is not
    positive definite."""
    n = len(A)
    if A.dtype != np.float64 or not (A.flags.c_contiguous or A.flags.f_contiguous):
        A = np.array(A, dtype=np.float64, order="F")
    x = np.array(b, dtype=np.float64, order="F").reshape(n, -1)
    if _DPOSV is None:
        _, x, info = lapack.dposv(A if A.flags.f_contiguous else A.T, x, lower=1)
    else:
        ints = np.array([n, x.shape[1], 0], dtype=np.intc)  # n (also lda, ldb), nrhs, info
        p, size = ints.ctypes.data, ints.itemsize
        _DPOSV(b"L", p, p + size, A.ctypes.data, p, x.ctypes.data, p, p + 2 * size)
        info = int(ints[2])
    if info != 0:
        raise np.linalg.LinAlgError(f"dposv failed (info {info}): the matrix is not positive definite")
    return x.reshape(np.shape(b))


def _raise_if_failed(info: int, j: int) -> None:
    if info > 0:
        raise InternalError(
            f"column solve: system {j} is not positive definite (leading minor {info}); "
            "G must be symmetric positive semi-definite"
        )
    if info < 0:
        raise InternalError(f"column solve: LAPACK dposv rejected argument {-info}")
