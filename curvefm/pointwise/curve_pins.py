"""The user's curves as constraints on pointwise maps: samples of a source curve map onto its target curve.

Refining converters (``icp``, ``zoomout``, ``rhm``) apply :class:`CurvePins` after each pointwise step, so
whatever the refinement does elsewhere, the curves the user drew stay where the user said. A vertex of a
source curve goes to the vertex of the target curve at the nearest normalised arc length, and vice versa.

Map directions follow :mod:`curvefm.pointwise.conversion`: ``p2p_NM[j]`` is the vertex of M for vertex j of N.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from curvefm.geometry import Mesh

FREE = -1  # a vertex no curve pins


def arc_parameter(vertices: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Arc length from the start of ``path`` to each of its vertices, divided by its length (0..1)."""
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(vertices[path], axis=0), axis=1))]
    return arc / arc[-1] if arc[-1] > 0 else np.zeros(len(path))


def partners_along(vertices_from: np.ndarray, path_from: np.ndarray, vertices_to: np.ndarray, path_to: np.ndarray):
    """For each vertex of ``path_from``, the vertex of ``path_to`` at the nearest normalised arc length."""
    t_from, t_to = arc_parameter(vertices_from, path_from), arc_parameter(vertices_to, path_to)
    nearest = np.abs(t_from[:, None] - t_to[None, :]).argmin(axis=1)
    return path_to[nearest]


@dataclass(frozen=True)
class CurvePins:
    """Fixed partners: ``M_to_N[x]`` is the vertex of N that vertex x of M must map to (``FREE`` if none),
    ``N_to_M[y]`` likewise for vertex y of N."""

    M_to_N: np.ndarray
    N_to_M: np.ndarray

    @classmethod
    def from_curves(cls, mesh_M: Mesh, mesh_N: Mesh, paths: Sequence[tuple[np.ndarray, np.ndarray]]) -> CurvePins:
        """Pins from corresponding vertex paths ``(path_M, path_N)`` (internal ids); where curves share a
        vertex, the later curve's partner wins."""
        pins = no_pins(mesh_M.n_vertices, mesh_N.n_vertices)
        M_to_N, N_to_M = pins.M_to_N, pins.N_to_M
        for path_M, path_N in paths:
            path_M, path_N = np.asarray(path_M, dtype=np.int64), np.asarray(path_N, dtype=np.int64)
            M_to_N[path_M] = partners_along(mesh_M.vertices, path_M, mesh_N.vertices, path_N)
            N_to_M[path_N] = partners_along(mesh_N.vertices, path_N, mesh_M.vertices, path_M)
        return pins

    def pin_MN(self, p2p_MN: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """``p2p_MN`` (one entry per vertex of M, or per vertex in ``rows``) with the pinned entries fixed."""
        return _pinned(p2p_MN, self.M_to_N if rows is None else self.M_to_N[rows])

    def pin_NM(self, p2p_NM: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """``p2p_NM`` (one entry per vertex of N, or per vertex in ``rows``) with the pinned entries fixed."""
        return _pinned(p2p_NM, self.N_to_M if rows is None else self.N_to_M[rows])


def _pinned(p2p: np.ndarray, partners: np.ndarray) -> np.ndarray:
    return np.where(partners != FREE, partners, p2p)


def no_pins(n_M: int, n_N: int) -> CurvePins:
    """Pins that fix nothing, for shapes of ``n_M`` and ``n_N`` vertices (a converter called without curves)."""
    return CurvePins(np.full(n_M, FREE, dtype=np.int64), np.full(n_N, FREE, dtype=np.int64))
