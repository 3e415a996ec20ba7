"""Pieces shared by the refining converters (``icp``, ``zoomout``, ``rhm``).

Every refiner starts from the same pointwise maps as the ``nearest-neighbor`` converter (both functional
maps at once, :func:`curvefm.pointwise.conversion.pointwise_from_both`) and from then on works with pointwise maps
only. So the bases it uses afterwards may be larger than the ``k x k`` of ``C_MN`` and ``C_NM``, and may even
be computed afresh (eigenvector signs do not matter once the maps are pointwise).

Map directions follow :mod:`curvefm.pointwise.conversion`: ``p2p_NM[j]`` is the vertex of M for vertex j of N.
"""

from __future__ import annotations

import numpy as np

from curvefm import registry
from curvefm.geometry import Mesh, MeshReport, farthest_point_sampling
from curvefm.pointwise.conversion import MapProblem, PointwiseMaps, pointwise_from_both
from curvefm.progress import Progress, no_progress, scaled
from curvefm.spectral import Basis


def surface(vertices: np.ndarray, faces: np.ndarray) -> Mesh:
    """A :class:`Mesh` around arrays that already are a valid internal mesh (those of a MapProblem)."""
    n = len(vertices)
    return Mesh(vertices, faces, np.arange(n, dtype=np.int64), n, MeshReport())


def unit_area_vertices(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The vertices scaled so that the surface has total area 1 (the scale of every basis)."""
    return vertices / np.sqrt(surface(vertices, faces).area)


def initial_maps(problem: MapProblem, search: str = "faiss") -> PointwiseMaps:
    """The ``nearest-neighbor`` converter's maps (both functional maps at once), where refinement starts."""
    M, N = problem.basis_M, problem.basis_N
    return PointwiseMaps(
        p2p_NM=pointwise_from_both(problem.C_MN, problem.C_NM, M, N, search),
        p2p_MN=pointwise_from_both(problem.C_NM, problem.C_MN, N, M, search),
    )


def bases_with(problem: MapProblem, k: int, progress: Progress = no_progress) -> tuple[Basis, Basis]:
    """Bases of M and N with at least ``k`` functions: the problem's own, or, where one is too small, the
    default ``laplace-beltrami`` basis computed here (a worker can do that; it costs seconds per shape)."""
    return (
        _basis_with(problem.basis_M, problem.vertices_M, problem.faces_M, k, scaled(progress, 0.0, 0.5)),
        _basis_with(problem.basis_N, problem.vertices_N, problem.faces_N, k, scaled(progress, 0.5, 1.0)),
    )


def _basis_with(basis: Basis, vertices: np.ndarray, faces: np.ndarray, k: int, progress: Progress) -> Basis:
    if basis.k >= k:
        return basis
    progress(0.0, f"computing a {k}-function basis (the session's has {basis.k})")
    plugin = registry.get("basis", "laplace-beltrami")
    return plugin.run(surface(vertices, faces), k, plugin.parse_params({}), progress)


def spread_samples(vertices: np.ndarray, faces: np.ndarray, count: int) -> np.ndarray:
    """``count`` (at most every) vertices spread by geodesic farthest-point sampling, from vertex 0."""
    return farthest_point_sampling(surface(vertices, faces), min(count, len(vertices)))
