"""How well the live maps agree with each other, per vertex and without ground truth: the round trip N -> M -> N.

A vertex of the target carried to the source by ``C_NM`` and back by ``C_MN`` should land where it started.
We carry the target's own coordinates (scaled to unit area and centred, so the figure is in units of
``sqrt(area)``, the unit of the project's geodesic error) and measure, at every vertex, how far the round trip
moves them:

    drift_N = | Psi (C_MN C_NM - I) a_N |   per vertex, with  a_N = Psi^T A_N x_N  (k x 3)

The coordinates are compared in their band-limited form ``Psi a_N``, so the basis truncation itself costs nothing:
a pair of exactly inverse maps drifts by zero everywhere. Why this measure:

* **informative**: where no curve constrains the maps, the commutativity term leaves their coefficients small,
  ``C_MN C_NM`` loses those directions and vertices there fall towards the centroid (with no curve at all a vertex
  drifts by its distance from the centroid); near good curves both maps agree and the drift vanishes. So the
  worst region is where the user's next curve helps most. (A map that is consistent both ways but wrong, e.g.
  a left-right swap given by the curves themselves, looks fine: no measure without ground truth sees that.)
* **cheap**: ``a_N`` is projected once per session; an update is two k x k matrix-vector products and one
  n x k x 3 product (float32, the cost of one texture transfer, about 3 ms at 30k vertices), where the
  per-vertex round trip of an indicator would need n x k x k. The local area distortion of a functional map
  would need as much, and says little where the map is merely unconstrained.

The same is measured on the source (M -> N -> M) for the "where to click next" highlight on both shapes. That
highlight is the vertex that drifts furthest *clear of the curves* (further than :data:`CLEAR_OF_CURVES` from every
vertex of their paths): the end of a curve can drift most while a new curve there adds little, and a hint that
points at a curve the user drew reads as a fault. The distance is straight-line, not geodesic: a k-d tree query per
measure instead of a geodesic solve per curve, and at this radius the two differ only across narrow gaps (between
the legs), where leaving out a little more is harmless for a hint.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from curvefm.geometry import Mesh
from curvefm.spectral import Basis

CLEAR_OF_CURVES = 0.1
"""How far (units of ``sqrt(area)``, straight-line) the "where to click next" vertex lies from every curve: about
13 cm on a FAUST body, a hand's width. Where many curves leave no vertex that far, half of it, then a quarter."""


@dataclass(frozen=True)
class RoundTrip:
    """Per-vertex round-trip drift on both shapes (float32, internal vertex order, units of ``sqrt(area)``)."""

    target: np.ndarray
    source: np.ndarray
    score: float  # the target's drift averaged over its area: 0 for maps that are exact inverses
    worst_target: int  # internal id of the vertex that drifts furthest clear of the curves (where to click next)
    worst_source: int


class RoundTripQuality:
    """Built once per session from its meshes and bases (both truncated to the maps' size); :meth:`measure`
    takes the current maps."""

    def __init__(self, mesh_M: Mesh, basis_M: Basis, mesh_N: Mesh, basis_N: Basis):
        self._side_M = _Side(mesh_M, basis_M)
        self._side_N = _Side(mesh_N, basis_N)

    def measure(
        self, C_MN: np.ndarray, C_NM: np.ndarray, curves_M: np.ndarray | None = None, curves_N: np.ndarray | None = None
    ) -> RoundTrip:
        """``C_MN`` (k_N x k_M) and ``C_NM`` (k_M x k_N) as the solver gives them; ``curves_M``, ``curves_N``: the
        internal ids of the curves' path vertices on each shape, which the worst vertices keep clear of."""
        target = self._side_N.drift(C_MN @ C_NM)
        source = self._side_M.drift(C_NM @ C_MN)
        return RoundTrip(
            target=target,
            source=source,
            score=float(np.dot(self._side_N.mass, target)),
            worst_target=self._side_N.worst_clear_of(target, curves_N),
            worst_source=self._side_M.worst_clear_of(source, curves_M),
        )


class _Side:
    """One shape's centred unit-area coordinates in its basis, and the basis in float32 (the product with it is
    bound by reading it from memory; drift is shown as colour, where 1e-7 relative is exact enough)."""

    def __init__(self, mesh: Mesh, basis: Basis):
        self.points = mesh.vertices / np.sqrt(mesh.area)
        coordinates = self.points - basis.mass @ self.points  # the mass sums to 1: the centroid
        self.coefficients = basis.project(coordinates)
        self.evecs = basis.evecs.astype(np.float32)
        self.mass = basis.mass

    def worst_clear_of(self, drift: np.ndarray, curves: np.ndarray | None) -> int:
        """The vertex that drifts furthest among those further than :data:`CLEAR_OF_CURVES` from every vertex of
        ``curves``; where the curves cover the whole shape so, within half that distance, then a quarter (then
        the worst overall)."""
        if curves is None or len(curves) == 0:
            return int(np.argmax(drift))
        near = cKDTree(self.points[np.unique(curves)])
        distance = np.asarray(near.query(self.points, distance_upper_bound=CLEAR_OF_CURVES)[0])
        for radius in (CLEAR_OF_CURVES, CLEAR_OF_CURVES / 2, CLEAR_OF_CURVES / 4):
            clear = distance > radius
            if clear.any():
                return int(np.argmax(np.where(clear, drift, -np.inf)))
        return int(np.argmax(drift))

    def drift(self, round_trip: np.ndarray) -> np.ndarray:
        k = round_trip.shape[0]
        moved = (round_trip @ self.coefficients[:k] - self.coefficients[:k]).astype(np.float32)
        return np.linalg.norm(self.evecs[:, :k] @ moved, axis=1)
