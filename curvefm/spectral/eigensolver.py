"""The first k eigenpairs of ``L phi = lambda A phi`` for a sparse PSD ``L`` and a lumped (diagonal) ``A``.

Shift-invert block Lanczos on the standard symmetric form ``A^-1/2 L A^-1/2`` (A is diagonal). SuperLU
solves a block of right-hand sides at about half the cost per vector, and the full reorthogonalisation runs
as matrix-matrix products, where ARPACK spends most of its time in memory-bound matrix-vector ones.

Large meshes are sliced by eigenvalue index over child processes, e.g. ``[0, k/2)`` with the shift below
the spectrum and ``[k/2, k)`` with a shift in its middle (Weyl's law). The number of eigenvalues below such a
shift is the inertia of its factorisation (Sylvester), so the slices meet exactly: no gap, no overlap.
"""

from __future__ import annotations

import logging
import os
import pickle
import subprocess
import sys
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.sparse.linalg import norm as sparse_norm
from scipy.sparse.linalg import splu

from curvefm.errors import InternalError, InvalidInput

log = logging.getLogger(__name__)

SIGMA = -0.01  # the shift of the plain call; L - SIGMA*A is positive definite
BLOCK = 8
PARALLEL_MIN_VERTICES = 15_000  # below this, starting two Python processes costs about what it saves


class EigenError(InternalError):
    """The eigensolver failed (factorisation, convergence, a worker process): our failure, not the user's."""


def smallest_eigenpairs(
    L: sp.spmatrix, mass: np.ndarray, k: int, *, workers: int | None = None, tol: float = 1e-6
) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(evals, evecs)``: the k smallest eigenvalues, ascending, and mass-orthonormal eigenvectors.

    ``workers``: 1 computes in this process; p > 1 slices the spectrum over p child processes. Default: 2
    for at least ``PARALLEL_MIN_VERTICES`` vertices and two free cores, else 1.
    ``tol``: relative residual of the shift-inverted Ritz pairs; eigenvalue errors are about its square.
    """
    L = sp.csr_matrix(L, dtype=float)
    mass = np.asarray(mass, dtype=float)
    n = len(mass)
    if not 0 < k < n:
        raise InvalidInput(f"need 0 < k < n vertices, got k={k}, n={n}")
    if workers is None:
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        workers = 2 if n >= PARALLEL_MIN_VERTICES and k >= 16 and cores >= 2 else 1
    if n <= max(4 * k + 10 * BLOCK, 600):  # too small for a useful Krylov space
        return sla.eigh(L.toarray(), np.diag(mass), subset_by_index=[0, k - 1])
    if workers >= 2:
        try:
            return _sliced(L, mass, k, tol, min(workers, k))
        except (EigenError, OSError) as error:
            log.warning("spectrum slicing failed (%s); computing in this process", error)
    return index_range(L, mass, 0, k, tol)


def index_range(L: sp.csr_matrix, mass: np.ndarray, lo: int, hi: int, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs number ``lo .. hi-1`` (0-based, ascending), mass-orthonormal.

    ``lo == 0``: the shift is below the spectrum and the hi largest Ritz values of the inverse are wanted.
    Otherwise the shift sits mid-range and pairs on both sides of it are wanted (the extremes of the
    inverse); the inertia of ``L - sigma A`` fixes how many lie below it.
    """
    if lo == 0:
        sigma, lu, below = SIGMA, _factor(L, mass, SIGMA), 0
    else:
        middle = (lo + hi) / 2
        sigma = 4 * np.pi * middle / mass.sum()  # Weyl: lambda_j ~ 4 pi j / area
        for attempt in range(3):  # Weyl's estimate is good to ~10% on real meshes; rescale where it is not
            lu = _factor(L, mass, sigma)
            below = _inertia(lu)
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
    op: Callable[[np.ndarray], np.ndarray], n: int, n_top: int, n_bottom: int, tol: float, block: int = BLOCK
) -> tuple[np.ndarray, np.ndarray]:
    """The ``n_top`` largest and ``n_bottom`` smallest eigenpairs of the symmetric operator ``op`` (applied
    to n x block arrays): block Lanczos with full reorthogonalisation, no restart."""
    wanted = n_top + n_bottom
    max_dim = min(n - block, 6 * wanted + 40 * block) // block * block
    basis = np.empty((n, max_dim), order="F")
    t = np.zeros((max_dim, max_dim))
    q = np.linalg.qr(np.random.default_rng(0).standard_normal((n, block)))[0]
    b = np.zeros((block, block))
    m, check_at = 0, 2 * wanted + 8 * block  # fewer vectors never suffice: skip the checks until then
    while m + block <= max_dim:
        basis[:, m : m + block] = q
        m += block
        v = basis[:, :m]
        # three-term recurrence, then one full reorthogonalisation pass
        w = op(q)
        scale = np.abs(w).max()
        h = np.zeros((m, block))
        if m > block:
            w -= basis[:, m - 2 * block : m - block] @ b.T
            h[m - 2 * block : m - block] = b.T
        a = q.T @ w
        w -= q @ a
        h[m - block :] += a
        h2 = v.T @ w
        w -= v @ h2
        h += h2
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
    raise EigenError(f"block Lanczos did not converge within {max_dim} vectors")


def _factor(L: sp.csr_matrix, mass: np.ndarray, sigma: float):
    # No pivoting (diag_pivot_thresh=0) after a symmetric ordering: U = D L^T, so diag(U) has the inertia
    matrix = (L - sp.diags(sigma * mass)).tocsc()
    try:
        lu = splu(matrix, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    except RuntimeError as error:  # exactly singular: sigma hit an eigenvalue
        raise EigenError(f"factorising L - {sigma} A: {error}") from error
    # without pivoting an indefinite matrix can grow a tiny pivot: check the backward error of one solve
    rhs = np.random.default_rng(1).standard_normal(matrix.shape[0])
    x = lu.solve(rhs)
    scale = sparse_norm(matrix, np.inf) * np.abs(x).max() + np.abs(rhs).max()
    if np.abs(matrix @ x - rhs).max() > 1e-10 * scale:
        raise EigenError(f"unstable factorisation of L - {sigma} A")
    return lu


def _inertia(lu) -> int:
    """Number of negative eigenvalues of the factored symmetric matrix (Sylvester's law of inertia)."""
    if not np.array_equal(lu.perm_r, lu.perm_c):
        raise EigenError("SuperLU pivoted off the diagonal: no inertia")
    return int(np.count_nonzero(lu.U.diagonal() < 0))


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


def _in_subprocesses(jobs: list[tuple]) -> list[tuple[np.ndarray, np.ndarray]]:
    # Child processes with single-threaded BLAS (set before numpy loads; this process's BLAS threads cannot be
    # limited, and two solver threads each driving a 2-thread BLAS thrash 2 cores); not multiprocessing: no
    # fork of a threaded server, and daemonic workers may not have children
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    command = [sys.executable, "-P", os.path.abspath(__file__)]
    pipe = subprocess.PIPE
    procs = [subprocess.Popen(command, stdin=pipe, stdout=pipe, stderr=pipe, env=env) for _ in jobs]
    try:
        with ThreadPoolExecutor(len(procs)) as pool:
            outputs = list(pool.map(lambda p, job: p.communicate(pickle.dumps(job, protocol=5)), procs, jobs))
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
    for p, (_, err) in zip(procs, outputs, strict=True):
        if p.returncode != 0:
            raise EigenError(f"worker exited with {p.returncode}: {err.decode(errors='replace')[-2000:]}")
    return [pickle.loads(out) for out, _ in outputs]


if __name__ == "__main__":  # a slice worker: one job from stdin, its eigenpairs to stdout
    pickle.dump(index_range(*pickle.load(sys.stdin.buffer)), sys.stdout.buffer, protocol=5)
