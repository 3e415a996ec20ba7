"""The user's curves as constraints on pointwise maps: what the user said is exact, a traced interior is evidence.

Refining converters (``icp``, ``zoomout``, ``rhm``) apply :class:`CurvePins` after each pointwise step. Only a
curve's endpoints are what the user said (a traced curve's interior is a shortest path between them, on each
shape on its own), so only the endpoints are *hard* pins: each end of a source curve maps to the same end of its
target curve whatever the refinement does. The interior vertices get *soft* partners, the vertex of the partner
curve at the nearest normalised arc length, which a refiner may weigh as evidence (:attr:`CurvePins.along_M_to_N`;
ZoomOut blends them into its fits by ``curve_interior_weight``, docs/decisions.md#curve-pins). Hard-pinning the
interiors made refinement from more curves worse: traced curves do not follow each other exactly, and the
arc-length partners were farther from the truth than the map's own images in 17 of 18 runs
(experiments/curve_pins.py, experiments/pin_rule.py).

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


def partners_along(
    vertices_from: np.ndarray, path_from: np.ndarray, vertices_to: np.ndarray, path_to: np.ndarray
) -> np.ndarray:
    """For each vertex of ``path_from``, the vertex of ``path_to`` at the nearest normalised arc length."""
    t_from, t_to = arc_parameter(vertices_from, path_from), arc_parameter(vertices_to, path_to)
    nearest = np.abs(t_from[:, None] - t_to[None, :]).argmin(axis=1)
    return path_to[nearest]


@dataclass(frozen=True)
class CurvePins:
    """Fixed partners: ``M_to_N[x]`` is the vertex of N that vertex x of M must map to (``FREE`` if none),
    ``N_to_M[y]`` likewise for vertex y of N. ``along_M_to_N`` and ``along_N_to_M`` hold the soft partners of
    the curves' other vertices (``FREE`` at hard-pinned and free vertices)."""

    M_to_N: np.ndarray
    N_to_M: np.ndarray
    along_M_to_N: np.ndarray
    along_N_to_M: np.ndarray

    @classmethod
    def from_curves(
        cls,
        mesh_M: Mesh,
        mesh_N: Mesh,
        paths: Sequence[tuple[np.ndarray, np.ndarray]],
        hard_interiors: bool = False,
    ) -> CurvePins:
        """Pins from corresponding vertex paths ``(path_M, path_N)`` (internal ids): the ends of each path hard,
        its other vertices soft by arc length (hard too with ``hard_interiors``, for paths known to correspond
        vertex by vertex). Where curves share a vertex, a hard pin beats a soft one, else the later curve wins."""
        pins = no_pins(mesh_M.n_vertices, mesh_N.n_vertices)
        ends = [_ends(np.asarray(path_M), np.asarray(path_N)) for path_M, path_N in paths]
        for path_M, path_N in paths:
            path_M, path_N = np.asarray(path_M, dtype=np.int64), np.asarray(path_N, dtype=np.int64)
            pins.along_M_to_N[path_M] = partners_along(mesh_M.vertices, path_M, mesh_N.vertices, path_N)
            pins.along_N_to_M[path_N] = partners_along(mesh_N.vertices, path_N, mesh_M.vertices, path_M)
        if hard_interiors:
            pins.M_to_N[:], pins.N_to_M[:] = pins.along_M_to_N, pins.along_N_to_M
        for end_M, end_N in ends:
            pins.M_to_N[end_M], pins.N_to_M[end_N] = end_N, end_M
        pins.along_M_to_N[pins.M_to_N != FREE] = FREE
        pins.along_N_to_M[pins.N_to_M != FREE] = FREE
        return pins

    def pin_MN(self, p2p_MN: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """``p2p_MN`` (one entry per vertex of M, or per vertex in ``rows``) with the hard-pinned entries fixed."""
        return _pinned(p2p_MN, self.M_to_N if rows is None else self.M_to_N[rows])

    def pin_NM(self, p2p_NM: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """``p2p_NM`` (one entry per vertex of N, or per vertex in ``rows``) with the hard-pinned entries fixed."""
        return _pinned(p2p_NM, self.N_to_M if rows is None else self.N_to_M[rows])

    def along_MN(self, p2p_MN: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """``p2p_MN`` with the curves' other vertices sent to their soft partners (:meth:`pin_MN`'s rows)."""
        return _pinned(p2p_MN, self.along_M_to_N if rows is None else self.along_M_to_N[rows])

    def along_NM(self, p2p_NM: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """``p2p_NM`` with the curves' other vertices sent to their soft partners (:meth:`pin_NM`'s rows)."""
        return _pinned(p2p_NM, self.along_N_to_M if rows is None else self.along_N_to_M[rows])


def _ends(path_M: np.ndarray, path_N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two ends of each path, in corresponding order."""
    return np.array([path_M[0], path_M[-1]], dtype=np.int64), np.array([path_N[0], path_N[-1]], dtype=np.int64)


def _pinned(p2p: np.ndarray, partners: np.ndarray) -> np.ndarray:
    return np.where(partners != FREE, partners, p2p)


def no_pins(n_M: int, n_N: int) -> CurvePins:
    """Pins that fix nothing, for shapes of ``n_M`` and ``n_N`` vertices (a converter called without curves)."""
    free_M, free_N = np.full(n_M, FREE, dtype=np.int64), np.full(n_N, FREE, dtype=np.int64)
    return CurvePins(free_M, free_N, free_M.copy(), free_N.copy())
