"""Functional-map methods: ways of computing ``C_MN`` and ``C_NM`` from correspondence hints.

A method plugin (entry-point group ``curvefm.methods``) receives a ``ShapePair`` (both meshes and bases) and
:class:`Hints` (corresponding curves and landmarks) and returns a :class:`FunctionalMaps`. Built in:
``curves`` (ours, the paper), and the descriptor baselines the paper compares against:

* ``obcs12`` (Ovsjanikov et al. 2012): least squares on descriptor preservation ``C F_M = F_N`` plus Laplacian
  commutativity, with wave kernel signatures and wave kernel maps at the landmarks. Exact, per row of C.
* ``no17`` (Nogneng and Ovsjanikov 2017): the same plus descriptor commutativity ``C X_f = Y_f C`` with the
  multiplication operators of the descriptors, minimised with L-BFGS from the ``obcs12`` solution. With
  ``inputs="curves"`` the descriptors are the curves themselves as functions: the paper's "baseline test".

Energy normalisation, shared with the curve solver: descriptors have unit L2 norm under the mass, the
descriptor and commutativity terms are means over descriptors, eigenvalues are divided by the larger of the
two k-th eigenvalues.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from curvefm.errors import InternalError, InvalidInput
from curvefm.fmap.column_solve import solve_columns
from curvefm.spectral import Basis


def normalised_eigenvalues(basis_M: Basis, basis_N: Basis, k: int) -> tuple[np.ndarray, np.ndarray]:
    scale = max(basis_M.evals[k - 1], basis_N.evals[k - 1], 1e-12)
    return basis_M.evals[:k] / scale, basis_N.evals[:k] / scale


def descriptor_least_squares(
    F_from: np.ndarray, F_to: np.ndarray, lam_from: np.ndarray, lam_to: np.ndarray, mu: float
) -> np.ndarray:
    """OBCS12: ``C`` (k_to x k_from) minimising ``||C F_from - F_to||^2 / d + mu ||C Lam_from - Lam_to C||^2``.

    ``F_*`` are descriptor coefficients (k x d). The energy separates by rows of C; row i solves
    ``(F_from F_from^T / d + mu diag((lam_from - lam_to[i])^2)) c_i = F_from F_to[i]^T / d``.
    """
    d = F_from.shape[1]
    C_T = solve_columns(F_from @ F_from.T / d, F_from @ F_to.T / d, lam_from, lam_to, mu)
    return C_T.T


@dataclass(frozen=True)
class DescriptorEnergy:
    """NO17's energy for ``C`` (k_to x k_from) with its gradient:

    ``w_descr ||C F_from - F_to||^2 / d + mu ||C Lam_from - Lam_to C||^2 + w_comm sum_f ||C X_f - Y_f C||^2 / q``
    with ``X_f``/``Y_f`` the multiplication operators of descriptor f on each shape (q of them).
    """

    F_from: np.ndarray
    F_to: np.ndarray
    lam_from: np.ndarray
    lam_to: np.ndarray
    X: np.ndarray  # (q, k_from, k_from)
    Y: np.ndarray  # (q, k_to, k_to)
    mu: float
    w_descr: float = 1.0
    w_comm: float = 1.0

    def __call__(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        k_to, k_from = len(self.lam_to), len(self.lam_from)
        C = x.reshape(k_to, k_from)
        d, q = self.F_from.shape[1], max(len(self.X), 1)
        R_descr = C @ self.F_from - self.F_to
        D = (self.lam_to[:, None] - self.lam_from[None, :]) ** 2
        R_comm = C @ self.X - self.Y @ C  # (q, k_to, k_from)
        value = self.w_descr * np.sum(R_descr**2) / d + self.mu * np.sum(D * C**2) + self.w_comm * np.sum(R_comm**2) / q
        grad = (
            2 * self.w_descr * R_descr @ self.F_from.T / d
            + 2 * self.mu * D * C
            + 2 * self.w_comm * np.sum(R_comm @ self.X - self.Y @ R_comm, axis=0) / q
        )
        return float(value), grad.ravel()


def lbfgs(energy, C0: np.ndarray, max_iter: int, tol: float = 1e-10) -> tuple[np.ndarray, int]:
    """Minimise ``energy(x) -> (value, grad)`` from ``C0`` with scipy's L-BFGS; ``(C, iterations)``."""
    result = minimize(
        energy, C0.ravel(), jac=True, method="L-BFGS-B",
        options={"maxiter": int(max_iter), "gtol": tol, "ftol": 1e-15, "maxcor": 20},
    )  # fmt: skip
    if not np.all(np.isfinite(result.x)):
        raise InternalError("the quasi-Newton solve diverged (non-finite map)")
    return result.x.reshape(C0.shape), int(result.nit)


def check_method_k(k: int, basis_M: Basis, basis_N: Basis) -> int:
    available = min(basis_M.k, basis_N.k)
    if k > available:
        raise InvalidInput(f"the method asks for k = {k} but the bases have only {available} functions")
    return k
