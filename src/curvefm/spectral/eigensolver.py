"""The first k eigenpairs of ``L phi = lambda A phi`` for a sparse PSD ``L`` and a lumped (diagonal) ``A``.

Shift-invert block Lanczos on the standard symmetric form ``A^-1/2 L A^-1/2`` (A is diagonal), with full
reorthogonalisation as matrix-matrix products (ARPACK spends its time in memory-bound matrix-vector ones)
and thick restarts, so the Krylov basis never exceeds about 2.5 k vectors. ``L - sigma A`` is factored
once by CHOLMOD (scikit-sparse, simplicial LDL^T with its AMD/METIS ordering) when it is installed, else by
SuperLU with the MMD_AT_PLUS_A ordering.

Why the SuperLU solver lost at scale (2026-11-22/23, FAUST subdivided, k = 120, single-threaded BLAS,
measured while other jobs ran, so absolute times are 3-9x a quiet machine's; the ratios hold):

* 28k vertices, one process: 19.4 s = 8.4 s in 368 SuperLU solves (23 ms a vector in blocks of 8),
  8.1 s of Lanczos products (reorthogonalisation and Ritz vectors), 1.3 s factorisation. Factor fill:
  SuperLU MMD 1.55 M (L + U), COLAMD 1.97 M, CHOLMOD 0.78 M (L only: symmetric); solve per vector in blocks
  of 8: 20.5 / 40.8 / 1.9 ms.
* 110k: CHOLMOD 4.4 M nonzeros (53 MB), 44-50 ms a vector; SuperLU's solves grow faster than n, and the two
  slice processes each factor and solve against one memory bus, so slicing lost to the plain call.
* 440k: SuperLU's MMD_AT_PLUS_A factorisation alone had not finished after 190 CPU seconds at 2.5 GB and
  growing (minimum degree on A + A^T without supernodes), once per slice process: that was the 17 GB and
  the 22 minutes. CHOLMOD: 24.6 M nonzeros (296 MB), 48 s, peak 0.85 GB for the process.
* The Lanczos basis was not the problem: ``np.empty`` touches only the pages used (368 of 680 vectors).

Large meshes can be sliced by eigenvalue index over processes (this one and children), e.g. ``[0, k/2)`` with
the shift below the spectrum and ``[k/2, k)`` with a shift in its middle (Weyl's law). The number of eigenvalues
below such a shift is the inertia of its factorisation (Sylvester), so the slices meet exactly: no gap, no
overlap. That only pays with a second idle core, so by default it is used only when the load average leaves at
least half of one: where that is wrong it costs the child's start, where a core is left idle half the solver's time.
"""

from __future__ import annotations

import logging
import os
import pickle
import subprocess
import sys
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.sparse.linalg import norm as sparse_norm
from scipy.sparse.linalg import splu

from curvefm.errors import InternalError, InvalidInput

try:  # CHOLMOD (scikit-sparse, optional): a third of SuperLU's fill and a fifth of its solve time on meshes
    from sksparse import cholmod
except ImportError:
    cholmod = None

log = logging.getLogger(__name__)

SIGMA = -0.01  # the shift of the plain call; L - SIGMA*A is positive definite
# chosen in docs/decisions.md#eigensolver
BLOCK = 16  # at 110k, 16 right-hand sides a solve beat 8 (0.51x vs 0.55x the plain call)
MAX_RESTARTS = 20
# chosen in docs/decisions.md#eigensolver
REORTHOGONALISE_BELOW = 0.1  # at 28k a block's first pass kept >= 0.17 of each column but where one was invariant
RESTART_ROWS = 65_536
# chosen in docs/decisions.md#eigensolver
PARALLEL_MIN_VERTICES = 15_000  # below this, starting two Python processes costs about what it saves
# chosen in docs/decisions.md#eigensolver
IDLE_CORE = 0.5  # the command's own benchmark keeps the 1-minute load average at about 1 on two cores


class EigenError(InternalError):
    """The eigensolver failed (factorisation, convergence, a worker process): our failure, not the user's."""


def smallest_eigenpairs(
    L: sp.csr_matrix | sp.csc_matrix, mass: np.ndarray, k: int, *, workers: int | None = None, tol: float = 1e-6
) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(evals, evecs)``: the k smallest eigenvalues, ascending, and mass-orthonormal eigenvectors.

    ``workers``: 1 computes in this process; p > 1 slices the spectrum over this process and p - 1 child
    processes. Default: 2 for at least ``PARALLEL_MIN_VERTICES`` vertices when the load average leaves at least
    ``IDLE_CORE`` of a core idle, else 1.
    ``tol``: relative residual of the shift-inverted Ritz pairs; eigenvalue errors are about its square.
    """
    L = sp.csr_matrix(L, dtype=np.float64)
    mass = np.asarray(mass, dtype=float)
    n = len(mass)
    if not 0 < k < n:
        raise InvalidInput(f"need 0 < k < n vertices, got k={k}, n={n}")
    if workers is None:
        workers = 2 if n >= PARALLEL_MIN_VERTICES and k >= 16 and _idle_cores() >= IDLE_CORE else 1
    if n <= max(4 * k + 10 * BLOCK, 600):  # too small for a useful Krylov space
        return sla.eigh(L.toarray(), np.diag(mass), subset_by_index=[0, k - 1])
    if workers >= 2:
        try:
            return _sliced(L, mass, k, tol, min(workers, k))
        except (EigenError, OSError) as error:
            log.warning("spectrum slicing failed (%s); computing in this process", error)
    return index_range(L, mass, 0, k, tol)


def _idle_cores() -> float:
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return cores - os.getloadavg()[0]


def index_range(L: sp.csr_matrix, mass: np.ndarray, lo: int, hi: int, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs number ``lo .. hi-1`` (0-based, ascending), mass-orthonormal.

    ``lo == 0``: the shift is below the spectrum and the hi largest Ritz values of the inverse are wanted.
    Otherwise the shift sits mid-range and pairs on both sides of it are wanted (the extremes of the
    inverse); the inertia of ``L - sigma A`` fixes how many lie below it.
    """
    if lo == 0:
        sigma, lu, below = SIGMA, shifted_factor(L, mass, SIGMA), 0
    else:
        middle = (lo + hi) / 2
        sigma = 4 * np.pi * middle / mass.sum()  # Weyl: lambda_j ~ 4 pi j / area
        for attempt in range(3):  # Weyl's estimate is good to ~10% on real meshes; rescale where it is not
            lu = shifted_factor(L, mass, sigma)
            below = lu.negative_pivots()
            if abs(below - middle) <= (hi - lo) / 4 or attempt == 2:
                break
            sigma *= middle / max(below, 1)
    first, last = min(lo, below), max(hi, below)  # computed: first .. last-1, a superset of lo .. hi-1
    s = np.sqrt(mass)

    def op(x: np.ndarray) -> np.ndarray:  # A^1/2 (L - sigma A)^-1 A^1/2: symmetric
        return s[:, None] * lu.solve(np.asfortranarray(s[:, None] * x))

    theta, y = block_lanczos(op, len(mass), n_top=last - below, n_bottom=below - first, tol=tol)
    evals = sigma + 1.0 / theta
    order = np.argsort(evals)[lo - first : hi - first]
    return evals[order], y[:, order] / s[:, None]


def block_lanczos(
    op: Callable[[np.ndarray], np.ndarray],
    n: int,
    n_top: int,
    n_bottom: int,
    tol: float,
    block: int = BLOCK,
    max_dim: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The ``n_top`` largest and ``n_bottom`` smallest eigenpairs of the symmetric operator ``op`` (applied
    to n x block arrays): block Lanczos with full reorthogonalisation and thick restarts.

    The Krylov basis holds at most ``max_dim`` vectors (default about 2.5 times the wanted number): when it is
    full, the wanted Ritz vectors and as many again as fit in half the spare room are kept and the
    recurrence goes on from the last residual block. Full reorthogonalisation makes the projected matrix
    ``T = V^T op V`` whatever its shape, so a restart only replaces ``V`` by Ritz vectors and ``T`` by their
    Ritz values; the next block's projections fill in the coupling.
    """
    wanted = n_top + n_bottom
    if max_dim is None:
        max_dim = 2 * wanted + 8 * block + wanted // 2
    max_dim = max(min(n - block, max_dim) // block * block, wanted + 2 * block)
    basis = np.empty((n, max_dim), order="F")
    t = np.zeros((max_dim, max_dim))
    q = np.linalg.qr(np.random.default_rng(0).standard_normal((n, block)))[0]
    m, check_at = 0, min(2 * wanted + 8 * block, max_dim)  # fewer vectors never suffice: skip the checks until then
    for _restart in range(MAX_RESTARTS + 1):
        while m + block <= max_dim:
            basis[:, m : m + block] = q
            m += block
            v = basis[:, :m]
            w = op(q)
            scale = np.abs(w).max()
            h = _orthogonalise(v, w)
            t[:m, m - block : m] = h
            t[m - block : m, :m] = h.T
            q, b = sla.qr(w, mode="economic")
            if np.abs(np.diag(b)).min() < 1e-10 * scale:  # (nearly) invariant subspace: stay orthogonal to it
                q = sla.qr(q - v @ (v.T @ q), mode="economic")[0]
            if m >= check_at or m + block > max_dim:
                theta, y = np.linalg.eigh(t[:m, :m])
                idx = np.r_[0:n_bottom, m - n_top : m]
                # op V = V T + q b E^T: a Ritz pair's residual is b times its last block of coordinates
                residual = np.linalg.norm(b @ y[m - block :, idx], axis=0)
                if np.all(residual <= tol * np.abs(theta[idx])):
                    return theta[idx], v @ y[:, idx]
                check_at = m + 2 * block
        m = _thick_restart(basis, t, theta, y, n_top, n_bottom, extra=(max_dim - wanted) // 2)
        check_at = m + 2 * block
    raise EigenError(f"block Lanczos did not converge within {MAX_RESTARTS} restarts of {max_dim} vectors")


def _orthogonalise(v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Remove from ``w`` (in place) its components along the orthonormal columns of ``v``; return them.

    Classical Gram-Schmidt, each pass two matrix-matrix products, and a second pass ("twice is enough") only where
    the first cancelled a column below ``REORTHOGONALISE_BELOW`` of its norm: the rounding a pass leaves grows like
    the inverse of that fraction (the Daniel-Gragg-Kaufman-Stewart test, with Rutishauser's factor 10)."""
    norms = np.linalg.norm(w, axis=0)
    h = v.T @ w
    w -= v @ h
    if np.any(np.linalg.norm(w, axis=0) < REORTHOGONALISE_BELOW * norms):
        h2 = v.T @ w
        w -= v @ h2
        h += h2
    return h


def _thick_restart(
    basis: np.ndarray, t: np.ndarray, theta: np.ndarray, y: np.ndarray, n_top: int, n_bottom: int, extra: int
) -> int:
    """Replace the basis by its wanted Ritz vectors and ``extra`` more (shared between the two ends like the
    wanted ones) and ``t`` by their Ritz values; return the new basis size."""
    m = len(theta)
    top = n_top + (extra * n_top) // (n_top + n_bottom)
    bottom = n_bottom + extra - (extra * n_top) // (n_top + n_bottom) if n_bottom else 0
    keep = np.r_[0:bottom, m - top : m]
    for rows in range(0, basis.shape[0], RESTART_ROWS):  # in place, a slab of rows at a time: no n x m copy
        slab = slice(rows, rows + RESTART_ROWS)
        basis[slab, : len(keep)] = basis[slab, :m] @ y[:, keep]
    t[:] = 0.0
    t[np.arange(len(keep)), np.arange(len(keep))] = theta[keep]
    return len(keep)


class _Factor:
    """A factorisation of the symmetric ``L - sigma A``: ``solve`` and ``negative_pivots`` (the inertia)."""

    def __init__(self, matrix: sp.csc_matrix):
        if cholmod is not None:
            self._cholmod = cholmod.cholesky(matrix, mode="simplicial")  # LDL^T: D holds the inertia
        else:
            # No pivoting (diag_pivot_thresh=0) after a symmetric ordering: U = D L^T, so diag(U) has the inertia
            options = {"SymmetricMode": True}
            self._lu = splu(matrix, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options=options)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return self._cholmod(rhs) if cholmod is not None else self._lu.solve(rhs)

    def negative_pivots(self) -> int:
        """Number of negative eigenvalues of the factored matrix (Sylvester's law of inertia)."""
        if cholmod is not None:
            return int(np.count_nonzero(self._cholmod.D() < 0))
        if not np.array_equal(self._lu.perm_r, self._lu.perm_c):
            raise EigenError("SuperLU pivoted off the diagonal: no inertia")
        return int(np.count_nonzero(self._lu.U.diagonal() < 0))


def shifted_factor(L: sp.csr_matrix, mass: np.ndarray, sigma: float) -> _Factor:
    """Factor ``L - sigma A`` (``A = diag(mass)``), checking the backward error of one solve."""
    matrix = (L - sp.diags(sigma * mass)).tocsc()
    try:
        factor = _Factor(matrix)
    except (RuntimeError, ArithmeticError) as error:  # exactly singular: sigma hit an eigenvalue
        raise EigenError(f"factorising L - {sigma} A: {error}") from error
    # without pivoting an indefinite matrix can grow a tiny pivot: check the backward error of one solve
    rhs = np.random.default_rng(1).standard_normal(matrix.shape[0])
    x = factor.solve(rhs)
    scale = sparse_norm(matrix, np.inf) * np.abs(x).max() + np.abs(rhs).max()
    if not np.all(np.isfinite(x)) or np.abs(matrix @ x - rhs).max() > 1e-10 * scale:
        raise EigenError(f"unstable factorisation of L - {sigma} A")
    return factor


def _sliced(L: sp.csr_matrix, mass: np.ndarray, k: int, tol: float, slices: int) -> tuple[np.ndarray, np.ndarray]:
    bounds = np.linspace(0, k, slices + 1).round().astype(int)
    parts = _in_subprocesses([(L, mass, lo, hi, tol) for lo, hi in zip(bounds[:-1], bounds[1:], strict=True)])
    evals = np.concatenate([p[0] for p in parts])
    evecs = np.hstack([p[1] for p in parts])
    gram = evecs.T @ (mass[:, None] * evecs)  # identity within a slice; ~tol across slices
    if np.any(np.diff(evals) < -1e-8 * evals[1:]) or np.abs(gram - np.eye(k)).max() > 1e-2:
        raise EigenError("the slices overlap: one of them missed an eigenvalue")
    # Loewdin: the nearest mass-orthonormal set; the eigenvalues stay those of the slices
    w, u = np.linalg.eigh(gram)
    return evals, evecs @ ((u / np.sqrt(w)) @ u.T)


def _in_subprocesses(jobs: list[tuple[Any, ...]]) -> list[tuple[np.ndarray, np.ndarray]]:
    """``index_range(*job)`` for each job: the first in this process, each other one in a child process started
    before it, so that the children's start (Python, numpy and scipy: about 0.4 s) overlaps this process's work."""
    from threadpoolctl import threadpool_limits  # here: a slice worker does not need it

    # Child processes with single-threaded BLAS (set before numpy loads), this process's limited while they run:
    # two solvers each driving a 2-thread BLAS thrash 2 cores. Not multiprocessing: no fork of a threaded server,
    # and daemonic workers may not have children
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    command = [sys.executable, "-P", os.path.abspath(__file__)]
    pipe = subprocess.PIPE
    procs = [subprocess.Popen(command, stdin=pipe, stdout=pipe, stderr=pipe, env=env) for _ in jobs[1:]]
    pool = ThreadPoolExecutor(max(len(procs), 1))
    try:
        talks = [
            pool.submit(p.communicate, pickle.dumps(job, protocol=5)) for p, job in zip(procs, jobs[1:], strict=True)
        ]
        with threadpool_limits(1):
            first = index_range(*jobs[0])
        outputs = [talk.result() for talk in talks]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
        pool.shutdown()
    for p, (_, err) in zip(procs, outputs, strict=True):
        if p.returncode != 0:
            raise EigenError(f"worker exited with {p.returncode}: {err.decode(errors='replace')[-2000:]}")
    return [first, *(pickle.loads(out) for out, _ in outputs)]


if __name__ == "__main__":  # a slice worker: one job from stdin, its eigenpairs to stdout
    pickle.dump(index_range(*pickle.load(sys.stdin.buffer)), sys.stdout.buffer, protocol=5)
