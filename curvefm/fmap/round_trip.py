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

The same is measured on the source (M -> N -> M) for the "where to click next" highlight on both shapes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from curvefm.geometry import Mesh
from curvefm.spectral import Basis


@dataclass(frozen=True)
class RoundTrip:
    """Per-vertex round-trip drift on both shapes (float32, internal vertex order, units of ``sqrt(area)``)."""

    target: np.ndarray
    source: np.ndarray
    score: float  # the target's drift averaged over its area: 0 for maps that are exact inverses
    worst_target: int  # internal id of the vertex that drifts furthest
    worst_source: int


class RoundTripQuality:
    """Built once per session from its meshes and bases (both truncated to the maps' size); :meth:`measure`
    takes the current maps."""

    def __init__(self, mesh_M: Mesh, basis_M: Basis, mesh_N: Mesh, basis_N: Basis):
        self._side_M = _Side(mesh_M, basis_M)
        self._side_N = _Side(mesh_N, basis_N)

    def measure(self, C_MN: np.ndarray, C_NM: np.ndarray) -> RoundTrip:
        """``C_MN`` (k_N x k_M) and ``C_NM`` (k_M x k_N) as the solver gives them."""
        target = self._side_N.drift(C_MN @ C_NM)
        source = self._side_M.drift(C_NM @ C_MN)
        return RoundTrip(
            target=target,
            source=source,
            score=float(np.dot(self._side_N.mass, target)),
            worst_target=int(np.argmax(target)),
            worst_source=int(np.argmax(source)),
        )


class _Side:
    """One shape's centred unit-area coordinates in its basis, and the basis in float32 (the product with it is
    bound by reading it from memory; drift is shown as colour, where 1e-7 relative is exact enough)."""

    def __init__(self, mesh: Mesh, basis: Basis):
        coordinates = mesh.vertices / np.sqrt(mesh.area)
        coordinates = coordinates - basis.mass @ coordinates  # the mass sums to 1: the centroid
        self.coefficients = basis.project(coordinates)
        self.evecs = basis.evecs.astype(np.float32)
        self.mass = basis.mass

    def drift(self, round_trip: np.ndarray) -> np.ndarray:
        k = round_trip.shape[0]
        moved = (round_trip @ self.coefficients[:k] - self.coefficients[:k]).astype(np.float32)
        return np.linalg.norm(self.evecs[:, :k] @ moved, axis=1)
