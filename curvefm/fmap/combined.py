"""The combined energy: curve constraints, descriptor preservation and landmark kernels in one exact solve.

``C_MN`` minimises, with the curve solver's normalisations (:mod:`curvefm.fmap.solver`),

    alpha ||C Lam_M - Lam_N C||^2
    + sum_l w~_l (1/s) ||PsiBar_l C - PhiBar_l||^2                         curves (the paper)
    + w_d (1/d) ||S_N^T C - S_M^T||^2                                        wave kernel signatures
    + w_k sum_l w~_l (1/d_l) ||K_N,l^T C - K_M,l^T||^2                       wave kernel maps along the curves

``S_M`` (k x d) are the coefficients of the wave kernel signatures of M (unit L2 norm each), ``K_M,l`` (k x d_l)
those of the wave kernel maps at ``KERNEL_POINTS`` samples of curve l, evenly spaced from its start to its end
(so its endpoints are landmarks): the wave kernel map at a point p with energy e has the coefficients
``g_e(lam) * phi(p)``, the basis restricted to p filtered by the energy's band, so a curve's kernels come from
the restriction ``PhiBar_l`` the curve term computes anyway. Corresponding samples on the two curves give
corresponding functions.

Why descriptors enter as ``||F_N^T C - F_M^T||`` (the adjoint ``C^T`` carries N's descriptors to M's) rather than
OBCS12's ``||C F_M - F_N||``: the two agree for the near-orthogonal maps of near-isometries, and the adjoint form
has exactly the shape of a curve term (the curve term is the same statement for the band-limited deltas at the
curve samples). So the whole energy still separates by columns: column j of C solves
``(G + alpha diag((lam^N_i - lam^M_j)^2)) c_j = B[:, j]`` with the descriptors' and kernels' k x k products added
to G and B, an edit re-sums k x k matrices, and the update stays exact and as fast as the pure curve energy
(:mod:`curvefm.fmap.column_solve`). OBCS12's form turns the normal equations into ``G C + C H + D o C = R``, which
has no direct solver; preconditioned conjugate gradients on it needed 20-400 iterations (0.1-1 s) at k = 120 in
our trials and was no more accurate (see the README, "The combined energy").

Descriptor commutativity (NO17) is not included: added on the leading 30 x 30 block of C and solved exactly
(benchmarks/bench_commutativity.py, 2026-11-23) it left FAUST 000 -> 011 with 2 curves at 0.053, improved
wolf0 -> wolf2 from 0.088 to 0.070 (NO17 with the endpoints: 0.011) and made cat -> lion worse (0.057 -> 0.078).
With few curves the curve terms themselves mislead: curves traced between corresponding endpoints do not
correspond point by point at equal arc length (a median 0.03-0.06 sqrt(area) off with 2 curves), so NO17's
energy with the endpoints beats any mix with them; see the README, "Descriptor commutativity in the combined
energy". Orientation terms were not tried.
"""

from __future__ import annotations

import numpy as np

from curvefm.cache import LRU
from curvefm.fmap.solver import CurveMapSolver, basis_digest
from curvefm.spectral import Basis, energy_filters, normalised, wave_kernel_signature

# Chosen by the sweep in benchmarks/bench_combined_weights.py (see the README, "Choosing the combined energy's
# weights"): 7% above the sweep's best mean (kernel weight 1000), which was 1.5-4x worse than the curve energy with
# one curve on cat -> lion in `curvefm reproduce`'s random curves; alpha stays the curve energy's.
DEFAULT_COMBINED_ALPHA = 100.0
DEFAULT_DESCRIPTOR_WEIGHT = 100.0
DEFAULT_KERNEL_WEIGHT = 100.0
KERNEL_POINTS = 2
ENERGIES = 20
SIGMA = 0.06

_SIGNATURES: LRU[np.ndarray] = LRU(16)  # by basis content: every session on a shape shares them


def signature_products(basis_M: Basis, basis_N: Basis) -> np.ndarray:
    """``[S_M S_M^T, S_N S_N^T, S_N S_M^T] / d`` (3 x k x k) for the wave kernel signatures of both shapes."""
    S_M, S_N = signature_coefficients(basis_M), signature_coefficients(basis_N)
    return np.stack([S_M @ S_M.T, S_N @ S_N.T, S_N @ S_M.T]) / S_M.shape[1]


def signature_coefficients(basis: Basis) -> np.ndarray:
    """Coefficients (k x ENERGIES) of the unit-norm wave kernel signatures of a basis; computed once per basis
    (cached by the basis's content, so every session on the same shape shares them)."""
    key = (basis_digest(basis), ENERGIES, SIGMA)
    return _SIGNATURES.get(key, lambda: basis.project(normalised(basis, wave_kernel_signature(basis, ENERGIES, SIGMA))))


def kernel_filters(evals: np.ndarray) -> np.ndarray:
    """The wave kernels' filters (ENERGIES x k - 1, the constant function skipped) for a basis's eigenvalues
    (unit-area mesh, not normalised: the filters are on log-eigenvalues)."""
    return energy_filters(evals, ENERGIES, SIGMA)


def kernel_coefficients(restricted: np.ndarray, filters: np.ndarray, points: int = KERNEL_POINTS) -> np.ndarray:
    """Unit-norm coefficients (k x points * ENERGIES) of the wave kernel maps at ``points`` samples of a curve.

    ``restricted`` (s x k) is the basis at the curve's s samples (a curve term's ``PhiBar``), ``filters`` the
    basis's :func:`kernel_filters`.
    """
    s, k = restricted.shape
    rows = np.unique(np.linspace(0, s - 1, points).round().astype(int))
    kernels = np.zeros((len(rows), ENERGIES, k))
    kernels[:, :, 1:] = restricted[rows, None, 1:] * filters[None]
    kernels = kernels.reshape(-1, k)
    kernels /= np.maximum(np.linalg.norm(kernels, axis=1, keepdims=True), 1e-300)
    return kernels.T


class CombinedMapSolver(CurveMapSolver):
    """:class:`CurveMapSolver` on the combined energy (module doc): same editing, ids, ``sync`` and threads.

    A curve is still stored as its two vertex paths; its k x k products (curve and kernel terms together) are
    computed from one restriction of the bases when it is added and again when it is removed or replaced.
    The signatures' products are fixed for the pair and added to the curves' sums at each solve.
    """

    def __init__(
        self,
        *args,
        alpha: float = DEFAULT_COMBINED_ALPHA,
        descriptor_weight: float = DEFAULT_DESCRIPTOR_WEIGHT,
        kernel_weight: float = DEFAULT_KERNEL_WEIGHT,
        kernel_points: int = KERNEL_POINTS,
        **kwargs,
    ):
        super().__init__(*args, alpha=alpha, **kwargs)
        self.descriptor_weight, self.kernel_weight = float(descriptor_weight), float(kernel_weight)
        self.kernel_points = kernel_points
        self._signatures = self.descriptor_weight * signature_products(self.basis_M, self.basis_N)
        self._filters_M, self._filters_N = kernel_filters(self.basis_M.evals), kernel_filters(self.basis_N.evals)

    def _side_factor(self, side: str, path: np.ndarray) -> np.ndarray:
        """The curve's factor on one side with its kernels' rows below, ``[PhiBar / sqrt(s); sqrt(w / p) K_M^T]``
        (and the same on N), so that the products sum the curve and kernel terms in one matrix product each."""
        restricted = self._restricted(side, path)
        kernels = kernel_coefficients(restricted, self._filters_M if side == "M" else self._filters_N,
                                      self.kernel_points)  # fmt: skip
        kernel_scale = np.sqrt(self.kernel_weight / kernels.shape[1])
        return np.vstack([restricted * (1.0 / np.sqrt(self.samples)), kernels.T * kernel_scale])

    def _factor_params(self) -> tuple:
        return (self.kernel_weight, self.kernel_points, ENERGIES, SIGMA)

    def normal_equations(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        G_M, G_N, B = super().normal_equations()
        W_M, W_N, W_B = self._signatures
        return G_M + W_M, G_N + W_N, B + W_B
