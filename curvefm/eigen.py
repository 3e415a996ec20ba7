"""The first k eigenpairs of ``L phi = lambda A phi`` for a sparse PSD ``L`` and a lumped (diagonal) ``A``."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh


def smallest_eigenpairs(L: sp.spmatrix, mass: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(evals, evecs)``: ascending eigenvalues and mass-orthonormal eigenvectors."""
    evals, evecs = eigsh(L.tocsc(), k=k, M=sp.diags(mass).tocsc(), sigma=-0.01)
    order = np.argsort(evals)
    return evals[order], evecs[:, order]
