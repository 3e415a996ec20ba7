"""Pointwise maps, and their conversion from functional maps by nearest neighbours in spectral embeddings.

Direction convention: ``p2p_NM[j]`` is the vertex of M matched to vertex j of N (a map N -> M). The
functional map ``C_MN`` (functions on M -> functions on N) yields ``p2p_NM`` (Ovsjanikov et al. 2012): the
image of a delta at vertex x of M has coefficients ``C_MN Phi[x]``, which should match ``Psi[y]`` at its
partner y.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from curvefm.pointwise.neighbors import nearest_neighbors
from curvefm.spectral import Basis

#: functions on the image side that :func:`orthogonal_steps` adds to the map's size (as the ``icp`` converter's 50 x
#: 80: square maps drift, see :mod:`curvefm.plugins.icp`)
ORTHOGONAL_EXTRA = 30
#: the smallest block :func:`room_for_steps` converts from (the landmark prior's size)
STEPPED_FROM = 50


@dataclass(frozen=True)
class PointwiseMaps:
    p2p_NM: np.ndarray  # (n,) vertex of M for each vertex of N
    p2p_MN: np.ndarray  # (m,) vertex of N for each vertex of M


def pointwise_from_fmap(
    C_MN: np.ndarray, basis_M: Basis, basis_N: Basis, search: str = "auto", rows: np.ndarray | None = None
) -> np.ndarray:
    """``p2p_NM`` from ``C_MN`` alone: for each y of N the x of M minimising ``|C_MN Phi[x] - Psi[y]|``.

    With ``rows`` only those vertices of N are matched (the result has one entry per row)."""
    k_N, k_M = C_MN.shape
    queries = basis_N.evecs[:, :k_N] if rows is None else basis_N.evecs[rows, :k_N]
    return nearest_neighbors(basis_M.evecs[:, :k_M] @ C_MN.T, queries, search)


def pointwise_from_both(
    C_MN: np.ndarray,
    C_NM: np.ndarray,
    basis_M: Basis,
    basis_N: Basis,
    search: str = "auto",
    rows: np.ndarray | None = None,
) -> np.ndarray:
    """``p2p_NM`` using both maps: for each y of N the x of M minimising
    ``|C_MN Phi[x] - Psi[y]|^2 + |Phi[x] - C_NM Psi[y]|^2``. With ``rows`` only those vertices of N are matched.

    Measured on FAUST 000 -> 011 with 10 curves this lowers the error from 0.0315 to 0.0276 (by sqrt(area)),
    and on cat -> lion it is as good or better; see docs/accuracy.md."""
    k_N, k_M = C_MN.shape
    Phi = basis_M.evecs[:, :k_M]
    Psi = basis_N.evecs[:, :k_N] if rows is None else basis_N.evecs[rows, :k_N]
    return nearest_neighbors(_beside(Phi, C_MN, mapped_first=True), _beside(Psi, C_NM, mapped_first=False), search)


def _beside(E: np.ndarray, C: np.ndarray, mapped_first: bool) -> np.ndarray:
    """``[E C^T, E]`` (or ``[E, E C^T]``) in float32, written in place: the search runs in float32 anyway, and at
    scan resolution the float64 product, stacking and cast cost 2.5 times as long (440k vertices: 5.3 s vs 2.1 s)."""
    E32 = E.astype(np.float32)
    out = np.empty((len(E), C.shape[0] + E.shape[1]), dtype=np.float32)
    split = C.shape[0] if mapped_first else E.shape[1]
    mapped, plain = (out[:, :split], out[:, split:]) if mapped_first else (out[:, split:], out[:, :split])
    np.matmul(E32, C.T.astype(np.float32), out=mapped)
    plain[...] = E32
    return out


def nearest_orthogonal(C: np.ndarray) -> np.ndarray:
    """The matrix with orthonormal columns closest to ``C`` in Frobenius norm (``U V^T`` of its SVD)."""
    U, _, Vt = np.linalg.svd(C, full_matrices=False)
    return U @ Vt


def orthogonal_steps(
    p2p_NM: np.ndarray, basis_M: Basis, basis_N: Basis, k_M: int, k_N: int, steps: int, search: str = "auto"
) -> np.ndarray:
    """``p2p_NM`` after ``steps`` orthogonal steps at the functional map's own size (the ICP of Ovsjanikov et al.
    2012): fit the map of functions on M (``k_M``) to N that the pointwise map induces, with
    :data:`ORTHOGONAL_EXTRA` more functions on N where its basis has them, replace it by the nearest map with
    orthonormal columns (an isometry's, on unit-area bases) and match by nearest neighbours again. None where N's
    basis has no function beyond the map's: square steps drift (the curve energy's 120 x 120 map from 10 curves on
    FAUST 000 -> 011 went from 0.0276 to 0.0335)."""
    k_image = stepped_size(k_N, basis_N)
    if k_image <= k_N:
        return p2p_NM
    for _ in range(steps):
        C = nearest_orthogonal(fmap_from_pointwise(p2p_NM, basis_M, basis_N, k_M, k_image))
        p2p_NM = nearest_neighbors(basis_M.evecs[:, :k_M] @ C.T, basis_N.evecs[:, :k_image], search)
    return p2p_NM


def stepped_size(k_N: int, basis_N: Basis) -> int:
    """The image side's functions in :func:`orthogonal_steps`' maps: ``k_N`` and :data:`ORTHOGONAL_EXTRA` more where
    ``basis_N`` has them (no more than ``k_N``: no steps)."""
    return min(k_N + ORTHOGONAL_EXTRA, basis_N.k)


def room_for_steps(C_forward: np.ndarray, C_back: np.ndarray, basis_from: Basis) -> tuple[np.ndarray, np.ndarray]:
    """The maps' leading blocks that leave :data:`ORTHOGONAL_EXTRA` functions of ``basis_from`` (the matched shape's)
    for :func:`orthogonal_steps`, where the maps leave fewer and the blocks keep at least
    :data:`STEPPED_FROM` functions; else the maps. ``C_forward`` carries functions to ``basis_from``'s shape,
    ``C_back`` from it. The 120 x 120 maps' frequencies above 90 blurred the pointwise map more than the steps' fit to
    120 recovers (docs/decisions.md#orthogonal-steps-in-the-conversion)."""
    k = basis_from.k - ORTHOGONAL_EXTRA
    if C_forward.shape[0] <= k or k < STEPPED_FROM:
        return C_forward, C_back
    return np.ascontiguousarray(C_forward[:k, :k]), np.ascontiguousarray(C_back[:k, :k])


def fmap_from_pointwise(p2p_NM: np.ndarray, basis_M: Basis, basis_N: Basis, k_M: int, k_N: int) -> np.ndarray:
    """``C_MN`` (k_N x k_M) induced by a pointwise map N -> M: ``Psi^+ Pi Phi`` with the mass-weighted
    pseudo-inverse ``Psi^+ = Psi^T A_N``."""
    return basis_N.evecs[:, :k_N].T @ (basis_N.mass[:, None] * basis_M.evecs[p2p_NM, :k_M])
