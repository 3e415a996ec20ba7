"""Iterative reference solvers of the curve energy, for comparison with the exact column solves: the
paper's conjugate gradients (its Algorithm 2) and L-BFGS.
"""

from __future__ import annotations

import numpy as np


def conjugate_gradient_solve(
    G: np.ndarray,
    B: np.ndarray,
    lam_rows: np.ndarray,
    lam_cols: np.ndarray,
    alpha: float,
    C0: np.ndarray | None = None,
    tol: float = 1e-8,
    max_iter: int = 5000,
) -> tuple[np.ndarray, int]:
    """The paper's reference solver (its Algorithm 2): conjugate gradients on the whole k^2 system
    ``G C + alpha * D o C = B`` (``D[i, j] = (lam_rows[i] - lam_cols[j])^2``), one step length for all
    columns, optionally warm-started from ``C0``. Returns ``(C, iterations)``; stops when the residual's
    Frobenius norm falls below ``tol`` times that of ``B``."""
    D = alpha * (lam_rows[:, None] - lam_cols[None, :]) ** 2

    def apply(X: np.ndarray) -> np.ndarray:
        return G @ X + D * X

    C = np.zeros_like(B) if C0 is None else C0.copy()
    R = B - apply(C)
    P = R.copy()
    rr = np.sum(R * R)
    stop = (tol * np.linalg.norm(B)) ** 2
    for iteration in range(max_iter):
        if rr <= stop:
            return C, iteration
        AP = apply(P)
        step = rr / np.sum(P * AP)
        C += step * P
        R -= step * AP
        rr_new = np.sum(R * R)
        P = R + (rr_new / rr) * P
        rr = rr_new
    return C, max_iter


def quasi_newton_solve(
    G: np.ndarray,
    B: np.ndarray,
    lam_rows: np.ndarray,
    lam_cols: np.ndarray,
    alpha: float,
    C0: np.ndarray | None = None,
    tol: float = 1e-8,
    max_iter: int = 20000,
) -> tuple[np.ndarray, int]:
    """The same energy minimised with scipy's L-BFGS (the paper's quasi-Newton comparison). Stops when every
    residual entry is below ``tol * ||B|| / sqrt(size)``, which implies CG's Frobenius criterion.
    Returns ``(C, iterations)``."""
    D = alpha * (lam_rows[:, None] - lam_cols[None, :]) ** 2

    def energy(x: np.ndarray) -> tuple[float, np.ndarray]:
        C = x.reshape(B.shape)
        GC = G @ C
        return float(np.sum(C * (GC + D * C)) - 2 * np.sum(C * B)), (2 * (GC + D * C - B)).ravel()

    start = np.zeros(B.size) if C0 is None else C0.ravel()
    gtol = 2 * tol * np.linalg.norm(B) / np.sqrt(B.size)
    from scipy.optimize import minimize  # about 0.4 s to import: not for every command that imports curvefm.fmap

    result = minimize(
        energy,
        start,
        jac=True,
        method="L-BFGS-B",
        options={"maxiter": max_iter, "gtol": gtol, "ftol": 0.0, "maxcor": 20, "maxfun": 2 * max_iter},
    )
    return result.x.reshape(B.shape), int(result.nit)
