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

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from curvefm.geometry import closest_point_weights, fast_decimate
from curvefm.spectral.eigensolver import SIGMA, shifted_factor, smallest_eigenpairs

# chosen in docs/decisions.md#eigensolver
COARSE_VERTICES = 8_000
EXTRA = 40  # coarse eigenpairs beyond k: the subspace iteration converges like (lambda_k / lambda_{k+extra})^steps
REFINE_STEPS = 1  # 110k vertices: eigenvalue error 1.3e-4 after one step, 3.5e-5 after two (at 1.4x the time)


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
    factor = shifted_factor(L, mass, SIGMA)
    for step in range(refine_steps):
        rhs = np.multiply(mass[:, None], x, order="F")  # CHOLMOD solves Fortran-ordered right-hand sides
        x = factor.solve(rhs)
        evals, coefficients = _rayleigh_ritz(mass, x, rhs)
        x = x @ coefficients[:, : k if step == refine_steps - 1 else None]
    return evals[:k], x


def prolongation(vertices: np.ndarray, faces: np.ndarray, coarse_vertices: int) -> sp.csr_matrix:
    """``P`` (n x n_coarse): row i holds the barycentric weights of vertex i's closest point on a decimated
    copy of the mesh, so the columns are the coarse mesh's hat functions seen from the full one. Coarse
    vertices that no row uses are dropped, so the coarse mass stays positive."""
    coarse_points, coarse_faces = fast_decimate(vertices, faces, coarse_vertices)
    matrix = closest_point_weights(vertices, coarse_points, coarse_faces)
    return matrix[:, np.flatnonzero(np.asarray(matrix.sum(axis=0)).ravel() > 0)].tocsr()


def _rayleigh_ritz(mass: np.ndarray, x: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ritz values (ascending) of ``L phi = lambda A phi`` on span(x), for ``x = (L - SIGMA A)^-1 rhs``, and the
    coefficients ``y`` that make ``x @ y`` the mass-orthonormal Ritz vectors. ``x^T L x`` is ``x^T rhs + SIGMA
    x^T A x``: no product with ``L``."""
    projected_mass = x.T @ (mass[:, None] * x)
    projected_L = x.T @ rhs + SIGMA * projected_mass
    scale = 1 / np.sqrt(np.diag(projected_mass))  # unit columns: shift-invert scales them apart
    projected_mass, projected_L = (scale[:, None] * m * scale for m in (projected_mass, projected_L))
    evals, y = sla.eigh((projected_L + projected_L.T) / 2, (projected_mass + projected_mass.T) / 2)
    return evals, scale[:, None] * y
