"""Error of pointwise maps against ground truth (Princeton-benchmark style).

Conventions
-----------
- A pointwise map ``p2p_XY`` is an integer array with one entry per vertex of X: ``p2p_XY[i]`` is the vertex
  of Y that vertex ``i`` of X is sent to. All ids here are *internal* mesh ids (see :mod:`curvefm.geometry.mesh`).
- Ground truth is a pair of equal-length arrays ``(ids_X, ids_Y)``: vertex ``ids_X[r]`` of X corresponds to
  vertex ``ids_Y[r]`` of Y. A vertex may appear in several rows (e.g. a many-to-one dense map).
- The error of a map X -> Y is measured **on Y**: for each row r, the geodesic distance on Y between the
  predicted partner ``p2p_XY[ids_X[r]]`` and the true partner ``ids_Y[r]``, divided by Y's geodesic diameter
  (the Princeton-benchmark normalisation, used for the cumulative curve) and, separately, by sqrt(area of Y).

Geodesic distances come from :mod:`curvefm.geometry.geodesics`.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from curvefm.errors import InvalidInput
from curvefm.geometry import Mesh, checked_ids, geodesic_diameter, pair_geodesic_distances

Truth = np.ndarray | tuple[ArrayLike, ArrayLike] | Iterable[np.ndarray]
"""Ground truth: ``(ids_X, ids_Y)``, an (m, 2) array of such rows, or a :class:`GroundTruth` (which unpacks so)."""

# Radii of the cumulative error curve, as fractions of the target's geodesic diameter.
CURVE_RADII = np.linspace(0.0, 0.25, 51)


# ----------------------------------------------------------------------------------------------------------
# Error summary


@dataclass
class ErrorSummary:
    """Geodesic errors of a pointwise map, measured on the target mesh.

    ``mean``/``median``/``max`` are divided by the target's geodesic diameter; ``mean_area``/``median_area``
    by sqrt(area of the target). ``curve[i]`` is the fraction of correspondences whose error (by diameter)
    is at most ``radii[i]`` (``radii`` = linspace(0, 0.25, 51)); ``auc`` is the normalised area under that
    curve (1 = every error is 0). ``count`` is the number of correspondences evaluated.
    """

    count: int
    mean: float
    median: float
    max: float
    mean_area: float
    median_area: float
    auc: float
    diameter: float
    sqrt_area: float
    radii: np.ndarray = field(repr=False)
    curve: np.ndarray = field(repr=False)
    distances: str = "dijkstra+unfolded-diagonals"

    @classmethod
    def from_distances(
        cls, distances: np.ndarray, diameter: float, area: float, method: str = "dijkstra+unfolded-diagonals"
    ) -> ErrorSummary:
        """Summarise raw geodesic errors (in the target's units)."""
        d = np.asarray(distances, dtype=np.float64).reshape(-1)
        if d.size == 0:
            raise InvalidInput("no correspondences to evaluate: the ground truth is empty")
        if not diameter > 0 or not area > 0:
            raise InvalidInput("cannot normalise errors: the target mesh has zero diameter or area")
        by_diam = d / diameter
        sqrt_area = float(np.sqrt(area))
        curve = (by_diam[None, :] <= CURVE_RADII[:, None] + 1e-12).mean(axis=1)
        auc = float(np.sum((curve[1:] + curve[:-1]) * np.diff(CURVE_RADII)) / 2 / CURVE_RADII[-1])
        return cls(
            count=int(d.size),
            mean=float(by_diam.mean()),
            median=float(np.median(by_diam)),
            max=float(by_diam.max()),
            mean_area=float(d.mean() / sqrt_area),
            median_area=float(np.median(d) / sqrt_area),
            auc=auc,
            diameter=float(diameter),
            sqrt_area=sqrt_area,
            radii=CURVE_RADII.copy(),
            curve=curve,
            distances=method,
        )

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-ready dict (lists for the curve; inf errors become None)."""

        def num(x: float) -> float | None:
            return float(x) if np.isfinite(x) else None

        return {
            "count": self.count,
            "mean": num(self.mean),
            "median": num(self.median),
            "max": num(self.max),
            "mean_area": num(self.mean_area),
            "median_area": num(self.median_area),
            "auc": num(self.auc),
            "diameter": self.diameter,
            "sqrt_area": self.sqrt_area,
            "normalisation": "mean/median/max/curve by geodesic diameter; *_area by sqrt(area); target mesh",
            "distances": self.distances,
            "radii": [float(r) for r in self.radii],
            "curve": [float(c) for c in self.curve],
        }


def _truth_arrays(truth: Truth) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(truth, np.ndarray) and truth.ndim == 2 and truth.shape[1] == 2:
        return truth[:, 0], truth[:, 1]
    try:
        ids_x, ids_y = truth
    except (TypeError, ValueError):
        raise InvalidInput(
            "ground truth must be a pair (ids_X, ids_Y) of equal-length id arrays or an (m, 2) array"
        ) from None
    ids_x, ids_y = np.asarray(ids_x).reshape(-1), np.asarray(ids_y).reshape(-1)
    if ids_x.shape != ids_y.shape:
        raise InvalidInput(f"ground truth sides differ in length: {ids_x.size} ids on X, {ids_y.size} on Y")
    return ids_x, ids_y


def map_geodesic_errors(p2p_XY: ArrayLike, truth: Truth, mesh_Y: Mesh, *, diagonals: bool = True) -> np.ndarray:
    """Raw geodesic errors on Y (in Y's units), one per ground-truth row.

    ``p2p_XY[i]`` is the vertex of Y for vertex i of X (internal ids); ``truth`` is ``(ids_X, ids_Y)``
    (internal ids: vertex ids_X[r] of X corresponds to ids_Y[r] of Y) or an (m, 2) array of such rows.
    """
    p2p = np.asarray(p2p_XY)
    if p2p.ndim != 1:
        raise InvalidInput(f"a pointwise map must be a 1-D array (one Y vertex per X vertex), got shape {p2p.shape}")
    ids_x, ids_y = _truth_arrays(truth)
    ids_x = checked_ids(ids_x, len(p2p), "ground-truth source (X) vertex")
    ids_y = checked_ids(ids_y, mesh_Y.n_vertices, "ground-truth target (Y) vertex")
    predicted = checked_ids(p2p, mesh_Y.n_vertices, "mapped (Y) vertex")[ids_x]
    return pair_geodesic_distances(mesh_Y, predicted, ids_y, diagonals=diagonals)


def evaluate_map(p2p_XY: ArrayLike, truth: Truth, mesh_Y: Mesh, *, diagonals: bool = True) -> ErrorSummary:
    """Princeton-benchmark geodesic error of the map X -> Y, measured on Y.

    Parameters
    ----------
    p2p_XY : (n_X,) int array
        ``p2p_XY[i]`` is the vertex of Y (internal id) that vertex i of X is mapped to.
    truth : (ids_X, ids_Y) or (m, 2) array or :class:`GroundTruth`
        Internal ids; vertex ``ids_X[r]`` of X truly corresponds to vertex ``ids_Y[r]`` of Y.
    mesh_Y : Mesh
        The target, on which distances are measured and by whose diameter / sqrt(area) they are divided.
    """
    errors = map_geodesic_errors(p2p_XY, truth, mesh_Y, diagonals=diagonals)
    method = "dijkstra+unfolded-diagonals" if diagonals else "dijkstra-edges"
    return ErrorSummary.from_distances(errors, geodesic_diameter(mesh_Y, diagonals=diagonals), mesh_Y.area, method)
