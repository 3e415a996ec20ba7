"""Loading a ground-truth pair once and scoring many functional maps on it cheaply, in both directions.

Scoring follows the Princeton protocol on a fixed, seeded sample of ground-truth rows (at most ``max_rows`` of a
dense truth; of a sparse landmark truth, the landmarks the curves of a seed were not drawn from), never at a
curve's end. Each direction has its own curves: ``source_to_target`` draws the endpoints on the source and maps each
sampled source vertex to the target by nearest neighbours in the spectral embedding of ``C_NM`` (Ovsjanikov et al.
2012, one map, as in the paper), the error measured on the target; ``target_to_source`` draws them on the target and
maps target vertices to the source with ``C_MN``, the error measured on the source. The geodesic distance to each
true partner is looked up in a table computed once per pair and direction.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from curvefm.evaluation.ground_truth import GroundTruth, ground_truth_for
from curvefm.evaluation.metrics import ErrorSummary
from curvefm.evaluation.protocol import ENDPOINT_SIDES, CurvePool, Curves, curve_ends, reversed_truth
from curvefm.evaluation.reproduce.datasets import Pair
from curvefm.fmap import FunctionalMaps
from curvefm.geometry import Mesh, geodesic_diameter, geodesic_distances, load_mesh
from curvefm.pointwise import pointwise_from_fmap
from curvefm.progress import Progress, no_progress, scaled
from curvefm.spectral import Basis, ShapePair
from curvefm.store import Store

MAX_ROWS = 1000
DIRECTIONS = {"source": "source_to_target", "target": "target_to_source"}
"""The map each side's curves are scored on: endpoints chosen on the source score the map source -> target."""


@dataclass
class LoadedPair:
    pair: Pair
    shapes: ShapePair
    truth: GroundTruth
    pools: dict[str, CurvePool]  # by the side the endpoints are chosen on
    scorers: dict[str, Scorer]  # likewise: the source's scores source -> target

    @classmethod
    def load(cls, data: Path, pair: Pair, k: int, store: Store, progress: Progress = no_progress) -> LoadedPair:
        mesh_M, mesh_N = load_mesh(data / pair.source), load_mesh(data / pair.target)
        truth = ground_truth_for(data / pair.source, data / pair.target, mesh_M, mesh_N)
        basis_M = store.ensure_basis(mesh_M, k, progress=scaled(progress, 0.0, 0.4))
        basis_N = store.ensure_basis(mesh_N, k, progress=scaled(progress, 0.4, 0.7))
        progress(0.7, f"{pair.name}: geodesic distances for scoring")
        scorers = {"source": Scorer.build(mesh_N, truth), "target": Scorer.build(mesh_M, reversed_truth(truth))}
        pools = {side: CurvePool(mesh_M, mesh_N, truth, endpoints_on=side) for side in ENDPOINT_SIDES}
        progress(1.0, f"{pair.name}: ready")
        return cls(pair, ShapePair(mesh_M, mesh_N, basis_M, basis_N), truth, pools, scorers)

    @property
    def pool(self) -> CurvePool:
        """The pool of curves with endpoints on the source."""
        return self.pools["source"]

    @property
    def max_curves(self) -> int:
        """The most distinct curves every seed can draw on either side."""
        return min(pool.max_curves for pool in self.pools.values())

    def score(self, C_NM: np.ndarray, seed: int, curves: Curves) -> ErrorSummary:
        """Errors source -> target of a map solved from ``curves`` drawn for ``seed`` with endpoints on the source
        (``pools["source"]``)."""
        return self._score("source", C_NM, seed, curves)

    def score_reverse(self, C_MN: np.ndarray, seed: int, curves: Curves) -> ErrorSummary:
        """Errors target -> source of a map solved from ``curves`` drawn for ``seed`` with endpoints on the target
        (``pools["target"]``)."""
        return self._score("target", C_MN, seed, curves)

    def score_side(self, maps: FunctionalMaps, side: str, seed: int, curves: Curves) -> ErrorSummary:
        """:meth:`score` or :meth:`score_reverse`, as ``side`` (where the endpoints were chosen) says."""
        if side == "source":
            return self.score(maps.C_NM, seed, curves)
        return self.score_reverse(maps.C_MN, seed, curves)

    def _score(self, side: str, C_to_from: np.ndarray, seed: int, curves: Curves) -> ErrorSummary:
        """Errors at the sampled rows the curves did not use: not at a curve's end, and of a sparse truth only at the
        seed's held-out landmarks (as :func:`~curvefm.evaluation.protocol.truth_to_score`)."""
        scorer, held_out = self.scorers[side], self.pools[side].held_out(seed)
        ends_M, ends_N = curve_ends(curves)
        ends_from, ends_to = (ends_M, ends_N) if side == "source" else (ends_N, ends_M)
        rows = ~np.isin(scorer.rows_from, ends_from) & ~np.isin(scorer.partners[scorer.columns], ends_to)
        if len(held_out):
            rows &= np.isin(scorer.rows_from, held_out)
        bases = (self.shapes.basis_M, self.shapes.basis_N)
        return scorer(C_to_from, *(bases if side == "source" else bases[::-1]), rows)


@dataclass
class Scorer:
    """A sample of ground-truth rows X -> Y and geodesic distances on Y from their true partners."""

    rows_from: np.ndarray  # sampled ground-truth rows: vertices of X...
    columns: np.ndarray  # ...and, for each, the row of `table` holding distances from its true partner
    partners: np.ndarray  # the distinct true partners (vertices of Y), in the order of `table`'s rows
    table: np.ndarray  # (distinct partners, n_Y) geodesic distances on Y
    diameter: float
    area: float

    @classmethod
    def build(cls, mesh_Y: Mesh, truth: GroundTruth, max_rows: int = MAX_ROWS, seed: int = 0) -> Scorer:
        rows = np.arange(len(truth))
        if len(rows) > max_rows:
            rows = np.sort(np.random.default_rng(seed).choice(rows, max_rows, replace=False))
        partners, columns = np.unique(truth.ids_Y[rows], return_inverse=True)
        table = geodesic_distances(mesh_Y, partners).astype(np.float32)
        return cls(truth.ids_X[rows], columns, partners, table, geodesic_diameter(mesh_Y), mesh_Y.area)

    def __call__(self, C_YX: np.ndarray, basis_X: Basis, basis_Y: Basis, rows: np.ndarray) -> ErrorSummary:
        """Errors at the sampled rows the mask ``rows`` selects, of the map X -> Y that ``C_YX`` (Y's coefficients
        to X's) induces."""
        predicted = pointwise_from_fmap(C_YX, basis_Y, basis_X, rows=self.rows_from[rows])
        return ErrorSummary.from_distances(self.table[self.columns[rows], predicted], self.diameter, self.area)
