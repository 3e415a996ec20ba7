"""Intrinsic quality of pointwise maps both ways: figures that need no ground truth.

* ``curve_residual``: mean distance from the images of the user's curves' vertices to the corresponding
  curve, both directions (0: every curve lands on its partner).
* ``coverage``: the fraction of each shape's area that the other shape's map reaches, averaged over both
  directions (1: surjective both ways).
* ``round_trip``: mean distance between a vertex and its image after going there and back (M -> N -> M and
  N -> M -> N), area-weighted (0: the two maps invert each other, i.e. bijective).

The curve residual and the round trip leave out the curves' ends: the refiners pin those, so a refined map would
look better exactly where it was told the answer (issue 35).
* ``inverse_deviation``: ``||C_NM C_MN - I||_F / sqrt(k)`` for the k x k functional maps the pointwise maps
  induce (0: inverse to each other on the first k frequencies).

``edge_stretch`` (one direction, for choosing between candidate maps): the mean length of the images of a shape's
edges over their mean length, in units of each shape's sqrt(area) (about 1 for a smooth map; seams where a region
lands flipped or elsewhere stretch edges across the target and raise it).

Distances are measured on the shapes scaled to unit area, so the figures do not depend on units.
:func:`compare` decides whether a refined map is worse than its start, figure by figure. What this cannot see
(experiments/refinement_guard.py, docs/decisions.md#the-refinement-guard): RHM minimises reversibility and pins the
curves, so curve residual, coverage and round trip improve wherever it runs. Before its anchor (plugins/rhm.py), RHM
ended a few percent worse than its start on 2 of the reproduce suite's 24 rows. Geodesic distortion, WKS preservation
and edge stretch did not flag those rows without also rejecting gains such as FAUST's. The anchor removed both
regressions inside RHM itself.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any, cast

import numpy as np
from scipy.spatial import cKDTree

from curvefm.geometry import Mesh
from curvefm.pointwise.conversion import PointwiseMaps, fmap_from_pointwise
from curvefm.spectral import ShapePair

QUALITY_K = 30  # frequencies of the induced functional maps for inverse_deviation
#: how much worse a figure may get before a refinement is reported as making the map worse
# chosen in docs/decisions.md#the-refinement-guard
TOLERANCE = {"coverage": 1e-2, "round_trip": 2e-3, "inverse_deviation": 2e-2}
#: the curve residual is reported, not judged: a traced curve's interior is evidence, not what the user said, and a
#: refined map may rightly leave it (docs/decisions.md#curve-pins). While every curve vertex was pinned, a refined
#: map's residual was 0 and never judged against either.
HIGHER_IS_BETTER = {"coverage"}


@dataclass(frozen=True)
class MapQuality:
    curve_residual: float | None  # None without curves
    coverage: float
    round_trip: float
    inverse_deviation: float

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def measure(pair: ShapePair, maps: PointwiseMaps, paths: Sequence[tuple[np.ndarray, np.ndarray]] = ()) -> MapQuality:
    """The intrinsic figures of ``maps`` between the shapes of ``pair``, given the user's curves ``paths``."""
    X_M = pair.mesh_M.vertices / np.sqrt(pair.mesh_M.area)
    X_N = pair.mesh_N.vertices / np.sqrt(pair.mesh_N.area)
    ends_M, ends_N = curve_ends(paths)
    a_M, a_N = _weights_off(pair.basis_M.mass, ends_M), _weights_off(pair.basis_N.mass, ends_N)
    coverage = 0.5 * (a_N[np.unique(maps.p2p_MN)].sum() + a_M[np.unique(maps.p2p_NM)].sum())
    round_trip = 0.5 * (
        a_M @ np.linalg.norm(X_M[maps.p2p_NM[maps.p2p_MN]] - X_M, axis=1)
        + a_N @ np.linalg.norm(X_N[maps.p2p_MN[maps.p2p_NM]] - X_N, axis=1)
    )
    return MapQuality(
        curve_residual=curve_residual(X_M, X_N, maps, paths),
        coverage=float(coverage),
        round_trip=float(round_trip),
        inverse_deviation=inverse_deviation(pair, maps),
    )


def curve_residual(
    X_M: np.ndarray, X_N: np.ndarray, maps: PointwiseMaps, paths: Sequence[tuple[np.ndarray, np.ndarray]]
) -> float | None:
    """Mean distance from mapped curve vertices to the partner curve (nearest vertex of it), both ways, over the
    curves' inner vertices (refiners pin the ends, so they would say nothing of the map)."""
    if not paths:
        return None
    distances = []
    for path_M, path_N in paths:
        inner_M, inner_N = path_M[1:-1], path_N[1:-1]
        distances.append(_to_curve(X_N[maps.p2p_MN[inner_M]], X_N[path_N]))
        distances.append(_to_curve(X_M[maps.p2p_NM[inner_N]], X_M[path_M]))
    return float(np.concatenate(distances).mean()) if sum(map(len, distances)) else 0.0


def curve_ends(paths: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """The vertices at either end of the curves, on M and on N: the points the user gave, which refiners pin."""
    ends_M = np.array([p[i] for p, _ in paths for i in (0, -1)], dtype=np.int64)
    ends_N = np.array([p[i] for _, p in paths for i in (0, -1)], dtype=np.int64)
    return ends_M, ends_N


def _weights_off(mass: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Vertex areas as weights summing to 1 over every vertex but ``rows``."""
    weights = mass.copy()
    weights[rows] = 0.0
    return weights / weights.sum()


def inverse_deviation(pair: ShapePair, maps: PointwiseMaps) -> float:
    k = min(QUALITY_K, pair.basis_M.k, pair.basis_N.k)
    C_MN = fmap_from_pointwise(maps.p2p_NM, pair.basis_M, pair.basis_N, k, k)
    C_NM = fmap_from_pointwise(maps.p2p_MN, pair.basis_N, pair.basis_M, k, k)
    return float(np.linalg.norm(C_NM @ C_MN - np.eye(k)) / np.sqrt(k))


def edge_stretch(mesh_from: Mesh, mesh_to: Mesh, p2p: np.ndarray) -> float:
    """How far the images of ``mesh_from``'s edges under ``p2p`` (a vertex of ``mesh_to`` per vertex) are apart,
    on average, relative to the edges themselves, each shape scaled to unit area."""
    a, b = mesh_from.edges.T
    before = np.linalg.norm(mesh_from.vertices[a] - mesh_from.vertices[b], axis=1).mean() / np.sqrt(mesh_from.area)
    after = np.linalg.norm(mesh_to.vertices[p2p[a]] - mesh_to.vertices[p2p[b]], axis=1).mean() / np.sqrt(mesh_to.area)
    return float(after / before)


def compare(refined: MapQuality, start: MapQuality) -> list[str]:
    """The figures on which ``refined`` is worse than ``start`` by more than :data:`TOLERANCE`, each as
    ``"name a -> b"``; empty when the refinement made no figure worse."""
    worse = []
    for name, slack in TOLERANCE.items():
        before, after = getattr(start, name), getattr(refined, name)
        if before is None or after is None:
            continue
        change = before - after if name in HIGHER_IS_BETTER else after - before
        if change > slack:
            worse.append(f"{name} {before:.4g} -> {after:.4g}")
    return worse


def _to_curve(points: np.ndarray, curve: np.ndarray) -> np.ndarray:
    return cast(np.ndarray, cKDTree(curve).query(points)[0])  # many points: an array of distances
