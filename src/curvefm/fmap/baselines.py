"""Functional-map methods: ways of computing ``C_MN`` and ``C_NM`` from correspondence hints.

A method plugin (entry-point group ``curvefm.methods``) receives a ``ShapePair`` (both meshes and bases) and
:class:`Hints` (corresponding curves and landmarks) and returns a :class:`FunctionalMaps`. Built in:
``curves`` (ours, the paper), and the descriptor baselines the paper compares against:

* ``obcs12`` (Ovsjanikov et al. 2012): least squares on descriptor preservation ``C F_M = F_N`` plus Laplacian
  commutativity, with wave kernel signatures and wave kernel maps at the landmarks. Exact, per row of C.
* ``no17`` (Nogneng and Ovsjanikov 2017): the same plus descriptor commutativity ``C X_f = Y_f C`` with the
  multiplication operators of the descriptors. The energy is quadratic in C, so it is minimised exactly (one
  Cholesky solve of its ``k^2`` normal equations) up to :data:`EXACT_MAX_K`, and by L-BFGS from the
  ``obcs12`` solution above that. With ``inputs="curves"`` the descriptors are the curves themselves as
  functions: the paper's "baseline test".

Energy normalisation: descriptors have unit L2 norm under the mass and eigenvalues are divided by the larger
of the two k-th eigenvalues. :func:`balanced_weights` then divides each term by its typical size, as pyFM
1.3 does (its ``canonical_taus``), so that the weights a user gives are relative and do not depend on how
many descriptors there are or how redundant they are.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from curvefm.errors import InternalError, InvalidInput
from curvefm.fmap.column_solve import solve_columns, solve_spd
from curvefm.spectral import Basis

EXACT_MAX_K = 64  # the k^2 x k^2 normal equations: 134 MB and about 1 s at k = 64; L-BFGS above


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

    def minimiser(self) -> np.ndarray:
        """The exact minimiser: the solution of the normal equations in ``vec(C)`` (C's rows concatenated).

        With symmetric operators, ``sum_f ||C X_f - Y_f C||^2`` has the Hessian (halved)
        ``I (x) S_X + S_Y (x) I - 2 sum_f Y_f (x) X_f``, ``S_X = sum_f X_f^2``; the last sum is made of products
        of the stacked operators. Solved by :func:`curvefm.fmap.column_solve.solve_spd` (a GIL-free Cholesky)."""
        k_to, k_from = len(self.lam_to), len(self.lam_from)
        d, q, n = self.F_from.shape[1], max(len(self.X), 1), k_to * k_from
        if len(self.X):  # -2 sum_f Y_f (x) X_f, in place: the k^2 x k^2 matrix is the only large array made
            # entry (i a, j b) is row (i, j) of the stacked Y times column (a, b) of the stacked X: k^2 products of
            # k x q by q x k matrices write it in its final layout (a tensordot then needed a strided copy, 3x
            # the time of the products at k = 50)
            Y_rows = np.ascontiguousarray(self.Y.transpose(1, 2, 0))  # (i, j, f)
            X_columns = np.ascontiguousarray(self.X.transpose(1, 0, 2))  # (a, f, b)
            H = np.matmul(Y_rows[:, None], X_columns[None]).reshape(n, n)
            H *= -2 * self.w_comm / q
            S_X, S_Y = np.einsum("fab,fbc->ac", self.X, self.X), np.einsum("fab,fbc->ac", self.Y, self.Y)
        else:
            H, S_X, S_Y = np.zeros((n, n)), 0.0, 0.0
        blocks = H.reshape(k_to, k_from, k_to, k_from)
        within_rows = self.w_descr / d * (self.F_from @ self.F_from.T) + self.w_comm / q * S_X
        for i in range(k_to):  # I (x) (descriptors + S_X)
            blocks[i, :, i, :] += within_rows
        for a in range(k_from):  # S_Y (x) I
            blocks[:, a, :, a] += self.w_comm / q * S_Y
        H.flat[:: n + 1] += self.mu * ((self.lam_to[:, None] - self.lam_from[None, :]) ** 2).ravel()
        rhs = self.w_descr / d * (self.F_to @ self.F_from.T).ravel()
        try:
            solution = solve_spd(H, rhs)
        except np.linalg.LinAlgError:
            raise InternalError("the descriptor energy is not strictly convex (no unique map)") from None
        return solution.reshape(k_to, k_from)

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


def effective_count(F: np.ndarray) -> float:
    """How many independent descriptors the coefficient columns ``F`` (k x d) hold:
    ``trace(G)^2 / ||G||_F^2`` for their Gram matrix G, the constant function left out (d for orthogonal
    descriptors of equal norm, 1 for d copies of one)."""
    inner = F[1:] @ F[1:].T  # same nonzero spectrum as the d x d Gram matrix, and smaller
    denominator = float(np.sum(inner**2))
    return float(np.trace(inner)) ** 2 / denominator if denominator > 0 else 1.0


def balanced_weights(
    F_from: np.ndarray,
    F_to: np.ndarray,
    lam_from: np.ndarray,
    lam_to: np.ndarray,
    X: np.ndarray,
    Y: np.ndarray,
    w_lap: float,
    w_comm: float,
) -> tuple[float, float, float]:
    """``(w_descr, mu, w_comm)`` for :class:`DescriptorEnergy` such that each term is divided by its typical
    size and then weighted relative to descriptor preservation (weight 1).

    Typical sizes (for a k x k map): descriptor preservation ``||F_from||^2 / p``, Laplacian commutativity the
    mean row sum of its mask, descriptor commutativity ``(k ||X||^2 + k ||Y||^2 - 2 sum_f tr X_f tr Y_f) / (k p)``,
    with ``p`` the :func:`effective_count` of the descriptors: redundant descriptors count once.
    """
    k_to, k_from = len(lam_to), len(lam_from)
    d, q = F_from.shape[1], max(len(X), 1)
    p = max(0.5 * (effective_count(F_from) + effective_count(F_to)), 1e-12)
    D = (lam_to[:, None] - lam_from[None, :]) ** 2
    size_descr = float(np.sum(F_from[1:] ** 2)) / p
    size_lap = float(D.sum()) / max(k_to, k_from)
    traces = np.trace(X, axis1=1, axis2=2) @ np.trace(Y, axis1=1, axis2=2) if len(X) else 0.0
    size_comm = (k_to * np.sum(X**2) + k_from * np.sum(Y**2) - 2 * traces) / (k_to * k_from) * min(k_to, k_from) / p
    w_descr = d / size_descr if size_descr > 0 else float(d)
    mu = w_lap / size_lap if size_lap > 0 else w_lap
    return w_descr, mu, (q * w_comm / size_comm if size_comm > 0 else 0.0)


def lbfgs(
    energy: Callable[[np.ndarray], tuple[float, np.ndarray]], C0: np.ndarray, max_iter: int, tol: float = 1e-10
) -> tuple[np.ndarray, int]:
    """Minimise ``energy(x) -> (value, grad)`` from ``C0`` with scipy's L-BFGS; ``(C, iterations)``."""
    from scipy.optimize import minimize  # about 0.4 s to import: not for every command that imports curvefm.fmap

    result = minimize(
        energy,
        C0.ravel(),
        jac=True,
        method="L-BFGS-B",
        options={"maxiter": int(max_iter), "gtol": tol, "ftol": 1e-15, "maxcor": 20},
    )
    if not np.all(np.isfinite(result.x)):
        raise InternalError("the quasi-Newton solve diverged (non-finite map)")
    return result.x.reshape(C0.shape), int(result.nit)


def check_method_k(k: int, basis_M: Basis, basis_N: Basis) -> int:
    available = min(basis_M.k, basis_N.k)
    if k > available:
        raise InvalidInput(f"the method asks for k = {k} but the bases have only {available} functions")
    return k
