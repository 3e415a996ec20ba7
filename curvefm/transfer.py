"""Carrying functions from M to N through a functional map: ``T U = Psi C_MN Phi^T A_M U``."""

from __future__ import annotations

import numpy as np

from curvefm.basis import Basis


def transfer(C_MN: np.ndarray, basis_M: Basis, basis_N: Basis, values_M: np.ndarray) -> np.ndarray:
    """Carry per-vertex values on M (shape (m,) or (m, d)) to per-vertex values on N."""
    return FunctionTransfer(basis_M, basis_N, values_M).apply(C_MN)


class FunctionTransfer:
    """A function on M projected once; :meth:`apply` carries it through any new map in O(n k d)."""

    def __init__(self, basis_M: Basis, basis_N: Basis, values_M: np.ndarray):
        self.values_shape = np.shape(values_M)[1:]
        self.coefficients = basis_M.project(values_M).reshape(basis_M.k, -1)
        self.evecs_N = basis_N.evecs

    def apply(self, C_MN: np.ndarray) -> np.ndarray:
        k_N, k_M = C_MN.shape
        out = self.evecs_N[:, :k_N] @ (C_MN @ self.coefficients[:k_M])
        return out.reshape((len(out),) + self.values_shape)
