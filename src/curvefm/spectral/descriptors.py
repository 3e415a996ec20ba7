"""Pointwise descriptors for the descriptor-based baselines (OBCS12, NO17) and their operators.

* Wave kernel signature (Aubry, Schlickewei, Cremers 2011): the probability that a quantum particle with
  energy distribution centred at log-energy ``e`` is measured at x,
  ``WKS(x, e) = sum_k phi_k(x)^2 g_e(lam_k) / sum_k g_e(lam_k)``, ``g_e(lam) = exp(-(e - log lam)^2 / 2 sigma^2)``.
* Wave kernel map at a landmark p: the same filter applied to ``phi_k(p) phi_k(x)``; corresponding landmarks
  on two shapes give corresponding functions, which is how OBCS12 uses landmarks.
* Curve functions (the paper's "baseline test"): -1 off a curve, its normalised arc length on it.
* Multiplication operators ``Phi^T A diag(f) Phi`` (Nogneng and Ovsjanikov 2017): a functional map that
  preserves a descriptor f should commute with multiplication by f. On scans (:data:`QUADRATURE_FROM_VERTICES`)
  they are integrated on :data:`QUADRATURE_POINTS` samples (:func:`scan_quadrature`): the products of a few
  hundred low frequencies are smooth, and the full sum costs ``n`` x d x k (k + 1) / 2 multiply-adds.

Energies are taken on the log-eigenvalues of the unit-area basis, skipping the constant eigenfunction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from curvefm.errors import InvalidInput
from curvefm.spectral.basis import Basis

OPERATOR_BLOCK = 2048  # vertices per block of products in multiplication_operators (bounds its memory)
# chosen in docs/decisions.md#descriptor-operators-on-scans
QUADRATURE_FROM_VERTICES = 200_000
"""From this many vertices on the multiplication operators are integrated on samples (:func:`scan_quadrature`);
below, and so at FAUST's size and the 110k scans, on every vertex as before."""
QUADRATURE_POINTS = 50_000
"""Samples of that quadrature: at 440,834 vertices the prior's operators differ from the full sums by 0.35%
(median, 0.9% at most; 100,000 samples: 0.23%), at a sixth of the time
(docs/decisions.md#descriptor-operators-on-scans)."""


@dataclass(frozen=True)
class Quadrature:
    """Integration on sample vertices: ``sum_i weights[i] g(rows[i])`` for ``sum_v mass[v] g(v)``."""

    rows: np.ndarray
    weights: np.ndarray

    def restrict(self, basis: Basis) -> Basis:
        """The basis at the samples, with the samples' weights as its mass."""
        return Basis(basis.evals, basis.evecs[self.rows], self.weights)


def scan_quadrature(vertices: np.ndarray, mass: np.ndarray, points: int | None = None) -> Quadrature | None:
    """None below :data:`QUADRATURE_FROM_VERTICES` vertices; else ``points`` (:data:`QUADRATURE_POINTS`) random
    vertices (seeded), each weighted by the mass of the vertices closest to it (its Voronoi cell on the surface,
    lumped). Samples spread evenly by a voxel grid did no better (440k: median operator error 0.28% against 0.35%,
    largest 1.2% against 0.9%): the error is the products' variation within a cell."""
    if len(vertices) < QUADRATURE_FROM_VERTICES:
        return None
    count = min(points or QUADRATURE_POINTS, len(vertices))
    rows = np.sort(np.random.default_rng(0).choice(len(vertices), count, replace=False))
    owner = cKDTree(vertices[rows]).query(vertices, workers=-1)[1]
    return Quadrature(rows, np.bincount(owner, weights=mass, minlength=len(rows)))


def _energy_filters(evals: np.ndarray, n_energies: int, sigma: float, margin: float = 0.0) -> np.ndarray:
    """(n_energies, k-1) normalised log-normal filters over the nonzero eigenvalues; ``sigma`` is the filter
    width as a fraction of the log-eigenvalue range (Aubry et al.'s variance 6 over 100 energies is 0.06).
    With ``margin`` the energies start and end that many filter widths inside the range, so no filter is
    centred where it sees only half its eigenvalues (pyFM's choice: 2)."""
    if n_energies < 1:
        raise InvalidInput(f"n_energies must be at least 1, got {n_energies}")
    if len(evals) < 3:
        raise InvalidInput(f"wave kernels need at least 3 basis functions, got {len(evals)}")
    log_lam = np.log(np.maximum(evals[1:], 1e-12))
    width = sigma * (log_lam[-1] - log_lam[0])
    energies = np.linspace(log_lam[0] + margin * width, log_lam[-1] - margin * width, n_energies)
    filters = np.exp(-((energies[:, None] - log_lam[None, :]) ** 2) / (2 * width**2))
    return filters / filters.sum(axis=1, keepdims=True)


def energy_filters(evals: np.ndarray, n_energies: int = 20, sigma: float = 0.06) -> np.ndarray:
    """The wave kernels' band filters ``g_e(lam_k)`` (n_energies x k-1, the constant eigenfunction skipped): the
    wave kernel map at p with energy e has the coefficients ``g_e(lam_k) phi_k(p)``."""
    return _energy_filters(evals, n_energies, sigma)


def wave_kernel_signature(
    basis: Basis, n_energies: int = 20, sigma: float = 0.06, *, margin: float = 0.0
) -> np.ndarray:
    """WKS, (n, n_energies), at energies evenly spaced over the log-eigenvalues (``margin``: see above)."""
    filters = _energy_filters(basis.evals, n_energies, sigma, margin)
    return (basis.evecs[:, 1:] ** 2) @ filters.T


def wave_kernel_maps(
    basis: Basis, landmarks: np.ndarray, n_energies: int = 20, sigma: float = 0.06, *, margin: float = 0.0
) -> np.ndarray:
    """Wave kernel maps at each landmark, (n, len(landmarks) * n_energies), grouped by landmark."""
    coefficients = wave_kernel_map_coefficients(basis, landmarks, n_energies, sigma, margin=margin)
    return basis.evecs[:, 1:] @ coefficients[1:]


def wave_kernel_map_coefficients(
    basis: Basis, landmarks: np.ndarray, n_energies: int = 20, sigma: float = 0.06, *, margin: float = 0.0
) -> np.ndarray:
    """The wave kernel maps' coefficients in ``basis`` (k, len(landmarks) * n_energies): they lie in its span,
    ``wave_kernel_maps == basis.evecs @ coefficients``; the constant eigenfunction's row is 0."""
    landmarks = np.asarray(landmarks, dtype=np.int64).reshape(-1)
    filters = _energy_filters(basis.evals, n_energies, sigma, margin)
    at_landmarks = basis.evecs[landmarks, 1:]  # (L, k-1)
    weights = at_landmarks[:, None, :] * filters[None, :, :]  # (L, E, k-1)
    return np.vstack([np.zeros((1, len(landmarks) * n_energies)), weights.reshape(-1, weights.shape[-1]).T])


def curve_function(vertices: np.ndarray, path: np.ndarray) -> np.ndarray:
    """-1 off the curve; on its vertices the arc length from its start divided by its length (0..1)."""
    path = np.asarray(path, dtype=np.int64)
    lengths = np.linalg.norm(np.diff(vertices[path], axis=0), axis=1)
    arc = np.r_[0.0, np.cumsum(lengths)]
    if arc[-1] <= 0:
        raise InvalidInput("a curve of zero length cannot be turned into a function")
    f = -np.ones(len(vertices))
    f[path] = arc / arc[-1]
    return f


def normalised(basis: Basis, functions: np.ndarray) -> np.ndarray:
    """Each column divided by its L2 norm under the mass (so descriptors weigh alike)."""
    norms = np.sqrt(basis.mass @ functions**2)
    return functions / np.maximum(norms, 1e-300)


def multiplication_operators(
    basis: Basis, functions: np.ndarray, k: int, quadrature: Quadrature | None = None
) -> np.ndarray:
    """``Phi^T A diag(f) Phi`` for each column f of ``functions``: (d, k, k), integrated on ``quadrature``'s
    samples where given.

    One matrix product for all of them: the operators are symmetric, so only the ``k (k + 1) / 2`` products
    ``A phi_a phi_b`` (a <= b) are formed, a block of vertices at a time, and every operator is a weighted sum
    of them."""
    if quadrature is not None:
        basis, functions = quadrature.restrict(basis), functions[quadrature.rows]
    Phi = basis.evecs[:, :k]
    rows, cols = np.triu_indices(k)
    packed = np.zeros((functions.shape[1], len(rows)))
    for start in range(0, len(Phi), OPERATOR_BLOCK):
        block = slice(start, start + OPERATOR_BLOCK)
        packed += functions[block].T @ ((basis.mass[block, None] * Phi[block][:, rows]) * Phi[block][:, cols])
    ops = np.empty((functions.shape[1], k, k))
    ops[:, rows, cols] = packed
    ops[:, cols, rows] = packed
    return ops
