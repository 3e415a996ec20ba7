"""An approximate eigenbasis for big meshes, computed on a coarse mesh and refined on the full one (in the
spirit of Nasikun, Brandt & Hildebrandt, "Fast Approximation of Laplace-Beltrami Eigenproblems", SGP 2018).

1. A coarse mesh of about ``coarse_vertices`` vertices by quadric decimation (Fast-Quadric-Mesh-Simplification).
2. A prolongation ``P`` (n x n_coarse, three weights a row): each vertex of the full mesh is written in
   barycentric coordinates of the closest point of the coarse mesh (open3d's ``RaycastingScene``).
3. The Galerkin restriction of the full operator onto the prolonged hat functions, ``P^T L P`` with the
   lumped ``P^T A P``: its first ``k + extra`` eigenpairs come from the exact solver at coarse size.
4. ``refine_steps`` subspace iterations on the full mesh, ``X <- (L - sigma A)^-1 A X`` with one
   factorisation, each followed by Rayleigh-Ritz with the full ``L`` and ``A``: the result is
   mass-orthonormal and its eigenvalues are Ritz values of the full operator (never below the exact ones).

The eigenvalue error is measured in benchmarks/bench_scan.py and checked in tests/spectral/test_multires.py.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from curvefm.geometry import closest_point_weights, fast_decimate
from curvefm.spectral.eigensolver import SIGMA, EigenError, shifted_factor, smallest_eigenpairs

# chosen in docs/decisions.md#eigensolver
COARSE_VERTICES = 8_000
EXTRA = 40  # coarse eigenpairs beyond k: the subspace iteration converges like (lambda_k / lambda_{k+extra})^steps
REFINE_STEPS = 1  # 110k vertices: eigenvalue error 1.3e-4 after one step, 3.5e-5 after two (at 1.4x the time)
# Scans of millions of vertices: the full-size work is done in blocks, so one n x (k + extra) array is the only
# large one besides the result (1.76M vertices, k = 120: 2.3 GB and 1.7 GB; whole-array temporaries were 4 more)
SOLVE_COLUMNS = 20
DEPENDENT_BELOW = 1e-10  # a direction of the refined subspace whose mass Gram eigenvalue is below this (relative)
ROW_BLOCK = 1 << 16


def multires_eigenpairs(
    L: sp.csr_matrix | sp.csc_matrix,
    mass: np.ndarray,
    vertices: np.ndarray,
    faces: np.ndarray,
    k: int,
    *,
    coarse_vertices: int = COARSE_VERTICES,
    refine_steps: int = REFINE_STEPS,
) -> tuple[np.ndarray, np.ndarray]:
    """Approximate ``(evals, evecs)`` of ``L phi = lambda A phi``, as :func:`smallest_eigenpairs` returns."""
    L = sp.csr_matrix(L, dtype=np.float64)
    mass = np.asarray(mass, dtype=float)
    prolong = prolongation(vertices, faces, max(coarse_vertices, 2 * (k + EXTRA)))
    coarse_mass = prolong.T @ mass  # P^T A P lumped, as for any hat functions: rows of P sum to 1
    coarse_L = (prolong.T @ L @ prolong).tocsr()
    count = min(k + EXTRA, prolong.shape[1] - 2)
    _, coarse_vecs = smallest_eigenpairs(coarse_L, coarse_mass, count, workers=1)
    x = prolong @ coarse_vecs
    del prolong, coarse_L
    factor = shifted_factor(L, mass, SIGMA)
    for _ in range(refine_steps - 1):
        _solve_in_place(factor.solve, mass, x)
        x = _rotated(x, _rayleigh_ritz(L, mass, x)[1])
    _solve_in_place(factor.solve, mass, x)
    del factor  # as big as x at scan size: gone before the result is made
    evals, rotation = _rayleigh_ritz(L, mass, x)
    if len(evals) < k:
        raise EigenError(f"the refined subspace holds {len(evals)} independent functions, fewer than k = {k}")
    return evals[:k], _rotated(x, rotation[:, :k])


def prolongation(vertices: np.ndarray, faces: np.ndarray, coarse_vertices: int) -> sp.csr_matrix:
    """``P`` (n x n_coarse): row i holds the barycentric weights of vertex i's closest point on a decimated
    copy of the mesh, so the columns are the coarse mesh's hat functions seen from the full one. Coarse
    vertices that no row uses are dropped, so the coarse mass stays positive."""
    coarse_points, coarse_faces = fast_decimate(vertices, faces, coarse_vertices)
    matrix = closest_point_weights(vertices, coarse_points, coarse_faces)
    return matrix[:, np.flatnonzero(np.asarray(matrix.sum(axis=0)).ravel() > 0)].tocsr()


def _solve_in_place(solve: Callable[[np.ndarray], np.ndarray], mass: np.ndarray, x: np.ndarray) -> None:
    """``x <- (L - sigma A)^-1 A x``, a few columns at a time."""
    for start in range(0, x.shape[1], SOLVE_COLUMNS):
        columns = slice(start, start + SOLVE_COLUMNS)
        x[:, columns] = solve(np.asfortranarray(mass[:, None] * x[:, columns]))


def _rayleigh_ritz(L: sp.csr_matrix, mass: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ritz values (ascending) and the rotation ``y`` that makes ``x @ y`` the mass-orthonormal Ritz vectors of
    ``L phi = lambda A phi`` on span(x); scales x's columns to unit mass norm in place (shift-invert scales them
    apart). Directions of x that are dependent to rounding are left out, so ``y`` may have fewer columns than x."""
    x /= np.sqrt(np.einsum("ij,i,ij->j", x, mass, x))
    m = x.shape[1]
    projected_mass, projected_L = np.zeros((m, m)), np.zeros((m, m))
    for rows in _row_blocks(len(x)):
        projected_mass += x[rows].T @ (mass[rows, None] * x[rows])
        projected_L += x[rows].T @ (L[rows] @ x)
    # Not a generalised eigh with the projected mass: shift-invert can turn two columns (nearly) parallel, and
    # then that Gram matrix is not positive definite to rounding (it failed once at 110k vertices)
    w, u = np.linalg.eigh((projected_mass + projected_mass.T) / 2)
    independent = w > DEPENDENT_BELOW * w[-1]
    orthonormal = u[:, independent] / np.sqrt(w[independent])
    evals, y = np.linalg.eigh(orthonormal.T @ ((projected_L + projected_L.T) / 2) @ orthonormal)
    return evals, orthonormal @ y


def _rotated(x: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    out = np.empty((len(x), rotation.shape[1]))
    for rows in _row_blocks(len(x)):
        out[rows] = x[rows] @ rotation
    return out


def _row_blocks(n: int) -> list[slice]:
    return [slice(start, start + ROW_BLOCK) for start in range(0, n, ROW_BLOCK)]
