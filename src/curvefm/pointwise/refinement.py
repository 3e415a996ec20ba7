"""Pieces shared by the refining converters (``icp``, ``zoomout``, ``rhm``).

Every refiner starts from nearest neighbours in the embedding of both functional maps at once
(:func:`curvefm.pointwise.conversion.pointwise_from_both`), without the ``nearest-neighbor`` converter's orthogonal
steps: from those, ZoomOut from 10 curves on FAUST 000 -> 011 (endpoints on the target) ended at 0.0112 / 0.0151
instead of 0.0113 / 0.0120 (docs/decisions.md#orthogonal-steps-in-the-conversion). From then on it works with
pointwise maps only. So the bases it uses afterwards may be larger than the ``k x k`` of ``C_MN`` and ``C_NM``, and
may even be computed afresh (eigenvector signs do not matter once the maps are pointwise).

Map directions follow :mod:`curvefm.pointwise.conversion`: ``p2p_NM[j]`` is the vertex of M for vertex j of N.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from curvefm.fmap import FunctionalMaps
from curvefm.geometry import Mesh, farthest_point_sampling
from curvefm.pointwise.conversion import PointwiseMaps, pointwise_from_both
from curvefm.progress import Progress, no_progress, scaled
from curvefm.spectral import Basis, ShapePair, laplace_beltrami_basis


def unit_area(mesh: Mesh) -> Mesh:
    """The mesh scaled to total area 1 (the scale of every basis)."""
    return dataclasses.replace(mesh, vertices=mesh.vertices / np.sqrt(mesh.area))


def initial_maps(
    pair: ShapePair,
    maps: FunctionalMaps,
    search: str = "auto",
    samples: tuple[np.ndarray, np.ndarray] | None = None,
) -> PointwiseMaps:
    """Maps from both functional maps at once, where refinement starts (the guard compares with the
    ``nearest-neighbor`` converter's).
    With ``samples`` ``(ids_M, ids_N)`` only those vertices are matched (to any vertex of the other shape):
    ``p2p_NM[r]`` is then the vertex of M for vertex ``ids_N[r]`` of N."""
    M, N = pair.basis_M, pair.basis_N
    ids_M, ids_N = samples if samples is not None else (None, None)
    return PointwiseMaps(
        p2p_NM=pointwise_from_both(maps.C_MN, maps.C_NM, M, N, search, ids_N),
        p2p_MN=pointwise_from_both(maps.C_NM, maps.C_MN, N, M, search, ids_M),
    )


def bases_with(pair: ShapePair, k: int, progress: Progress = no_progress) -> tuple[Basis, Basis]:
    """Bases of M and N with at least ``k`` functions: the pair's own, or, where one is too small, the
    default basis (:func:`curvefm.spectral.laplace_beltrami_basis`) computed here (a worker can do that; it costs
    seconds per shape)."""
    return (
        _basis_with(pair.basis_M, pair.mesh_M, k, scaled(progress, 0.0, 0.5)),
        _basis_with(pair.basis_N, pair.mesh_N, k, scaled(progress, 0.5, 1.0)),
    )


def _basis_with(basis: Basis, mesh: Mesh, k: int, progress: Progress) -> Basis:
    if basis.k >= k:
        return basis
    progress(0.0, f"computing a {k}-function basis (the session's has {basis.k})")
    return laplace_beltrami_basis(mesh, k, progress=progress)


def spread_samples(mesh: Mesh, count: int) -> np.ndarray:
    """``count`` (at most every) vertices spread by farthest-point sampling along edges, from vertex 0
    (without the face diagonals: 4,000 samples of 110k vertices in 1.8 s instead of 10 s)."""
    return farthest_point_sampling(mesh, min(count, mesh.n_vertices), diagonals=False)
