"""Loading a ground-truth pair once and scoring many maps on it cheaply, in both directions.

Scoring follows the Princeton protocol on a fixed, seeded sample of ground-truth rows (at most ``max_rows`` of a
dense truth; of a sparse landmark truth, the landmarks the curves of a seed were not drawn from), never at a
curve's end on either shape (:func:`~curvefm.evaluation.protocol.rows_to_score`, the rows
:func:`~curvefm.evaluation.protocol.truth_to_score` keeps). The geodesic distance from each sampled row's true
partner to every vertex is computed once per pair and direction, so scoring a map is a table look-up.

:meth:`LoadedPair.score_handed_out` scores what ``curvefm match`` hands out: both pointwise maps of the default
converter (:func:`curvefm.matching.handed_out`: nearest neighbours, then its orthogonal steps), source -> target
measured on the target and target -> source on the source, whichever side the curves' endpoints were chosen on.
:meth:`LoadedPair.score` and :meth:`LoadedPair.score_reverse` keep the older, cheaper score of the experiments
under ``experiments/`` (plain nearest neighbours in the embedding of one functional map, one direction).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from curvefm.evaluation.ground_truth import GroundTruth, ground_truth_for
from curvefm.evaluation.metrics import ErrorSummary
from curvefm.evaluation.protocol import ENDPOINT_SIDES, CurvePool, Curves, reversed_truth, rows_to_score
from curvefm.evaluation.reproduce.datasets import Pair
from curvefm.fmap import FunctionalMaps
from curvefm.geometry import Mesh, geodesic_diameter, geodesic_distances, load_mesh
from curvefm.matching import handed_out
from curvefm.pointwise import PointwiseMaps, pointwise_from_fmap
from curvefm.progress import Progress, no_progress, scaled
from curvefm.spectral import Basis, ShapePair
from curvefm.store import Store

MAX_ROWS = 1000
DIRECTIONS = {"source": "source_to_target", "target": "target_to_source"}
"""The direction read from each side: the map source -> target starts on the source. With endpoints chosen on a side,
that side's map is the one the paper's protocol (source) and issue 35's (target) score; the report gives both maps."""


@dataclass
class LoadedPair:
    pair: Pair
    shapes: ShapePair
    truth: GroundTruth
    pools: dict[str, CurvePool]  # by the side the endpoints are chosen on
    scorers: dict[str, Scorer]  # by the side the map starts on: the source's scores source -> target
    rows: np.ndarray  # the ground-truth rows both scorers sample (the same rows, read either way)

    @classmethod
    def load(cls, data: Path, pair: Pair, k: int, store: Store, progress: Progress = no_progress) -> LoadedPair:
        mesh_M, mesh_N = load_mesh(data / pair.source), load_mesh(data / pair.target)
        truth = ground_truth_for(data / pair.source, data / pair.target, mesh_M, mesh_N)
        basis_M = store.ensure_basis(mesh_M, k, progress=scaled(progress, 0.0, 0.4))
        basis_N = store.ensure_basis(mesh_N, k, progress=scaled(progress, 0.4, 0.7))
        progress(0.7, f"{pair.name}: geodesic distances for scoring")
        rows = sampled_rows(truth)
        scorers = {
            "source": Scorer.build(mesh_N, truth, rows),
            "target": Scorer.build(mesh_M, reversed_truth(truth), rows),
        }
        pools = {side: CurvePool(mesh_M, mesh_N, truth, endpoints_on=side) for side in ENDPOINT_SIDES}
        progress(1.0, f"{pair.name}: ready")
        return cls(pair, ShapePair(mesh_M, mesh_N, basis_M, basis_N), truth, pools, scorers, rows)

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

    def score_handed_out(
        self, fmaps: FunctionalMaps, side: str, seed: int, curves: Curves, k: int | None = None
    ) -> dict[str, ErrorSummary]:
        """Errors of both pointwise maps ``curvefm match --k k`` hands out for ``fmaps`` (:func:`handed_out` on the
        bases of ``k`` functions, all of the loaded ones by default), solved from ``curves`` drawn for ``seed`` with
        endpoints on ``side``: ``{"source_to_target": ..., "target_to_source": ...}``."""
        shapes = self.shapes if k is None else self.shapes.truncated(k)
        return self.score_pointwise(handed_out(shapes, fmaps), side, seed, curves)

    def score_pointwise(self, maps: PointwiseMaps, side: str, seed: int, curves: Curves) -> dict[str, ErrorSummary]:
        """Errors of both pointwise ``maps`` at the sampled rows :func:`rows_to_score` keeps for ``curves`` drawn for
        ``seed`` with endpoints on ``side``."""
        keep = rows_to_score(self.truth, curves, seed, side)[self.rows]
        return {
            DIRECTIONS["source"]: self.scorers["source"].pointwise(maps.p2p_MN, keep),
            DIRECTIONS["target"]: self.scorers["target"].pointwise(maps.p2p_NM, keep),
        }

    def _score(self, side: str, C_to_from: np.ndarray, seed: int, curves: Curves) -> ErrorSummary:
        """Errors of one map (plain nearest neighbours) at the sampled rows :func:`rows_to_score` keeps."""
        keep = rows_to_score(self.truth, curves, seed, side)[self.rows]
        bases = (self.shapes.basis_M, self.shapes.basis_N)
        return self.scorers[side](C_to_from, *(bases if side == "source" else bases[::-1]), keep)


def sampled_rows(truth: GroundTruth, max_rows: int = MAX_ROWS, seed: int = 0) -> np.ndarray:
    """At most ``max_rows`` ground-truth rows, seeded and sorted: all of a landmark truth, a sample of a dense one."""
    rows = np.arange(len(truth))
    if len(rows) > max_rows:
        rows = np.sort(np.random.default_rng(seed).choice(rows, max_rows, replace=False))
    return rows


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
    def build(
        cls, mesh_Y: Mesh, truth: GroundTruth, rows: np.ndarray | None = None, max_rows: int = MAX_ROWS
    ) -> Scorer:
        """The scorer of ``truth``'s ``rows`` (else of :func:`sampled_rows`, at most ``max_rows``)."""
        rows = sampled_rows(truth, max_rows) if rows is None else rows
        partners, columns = np.unique(truth.ids_Y[rows], return_inverse=True)
        table = geodesic_distances(mesh_Y, partners).astype(np.float32)
        return cls(truth.ids_X[rows], columns, partners, table, geodesic_diameter(mesh_Y), mesh_Y.area)

    def __call__(self, C_YX: np.ndarray, basis_X: Basis, basis_Y: Basis, rows: np.ndarray) -> ErrorSummary:
        """Errors at the sampled rows the mask ``rows`` selects, of the map X -> Y that ``C_YX`` (Y's coefficients
        to X's) induces."""
        predicted = pointwise_from_fmap(C_YX, basis_Y, basis_X, rows=self.rows_from[rows])
        return ErrorSummary.from_distances(self.table[self.columns[rows], predicted], self.diameter, self.area)

    def pointwise(self, p2p_XY: np.ndarray, rows: np.ndarray) -> ErrorSummary:
        """Errors at the sampled rows the mask ``rows`` selects of the pointwise map ``p2p_XY`` (a vertex of Y per
        vertex of X)."""
        predicted = p2p_XY[self.rows_from[rows]]
        return ErrorSummary.from_distances(self.table[self.columns[rows], predicted], self.diameter, self.area)
