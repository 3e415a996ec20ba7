"""Loading a ground-truth pair once and scoring many functional maps on it cheaply.

Scoring follows the Princeton protocol on a fixed, seeded sample of ground-truth rows (at most ``max_rows`` of a
dense truth; of a sparse landmark truth, the landmarks the curves of a seed were not drawn from): the source
vertex of each row is mapped to the target by nearest neighbours in the spectral embedding of ``C_NM``
(Ovsjanikov et al. 2012, one map, as in the paper) and the geodesic distance to its true partner is looked up
in a table computed once per pair.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from curvefm.evaluation.ground_truth import GroundTruth, ground_truth_for
from curvefm.evaluation.metrics import ErrorSummary
from curvefm.evaluation.protocol import CurvePool
from curvefm.evaluation.reproduce.datasets import Pair
from curvefm.geometry import Mesh, geodesic_diameter, geodesic_distances, load_mesh
from curvefm.pointwise import pointwise_from_fmap
from curvefm.progress import Progress, no_progress, scaled
from curvefm.spectral import Basis, ShapePair
from curvefm.store import Store

MAX_ROWS = 1000


@dataclass
class LoadedPair:
    pair: Pair
    shapes: ShapePair
    truth: GroundTruth
    pool: CurvePool
    scorer: Scorer

    @classmethod
    def load(cls, data: Path, pair: Pair, k: int, store: Store, progress: Progress = no_progress) -> LoadedPair:
        mesh_M, mesh_N = load_mesh(data / pair.source), load_mesh(data / pair.target)
        truth = ground_truth_for(data / pair.source, data / pair.target, mesh_M, mesh_N)
        basis_M = store.ensure_basis(mesh_M, k, progress=scaled(progress, 0.0, 0.4))
        basis_N = store.ensure_basis(mesh_N, k, progress=scaled(progress, 0.4, 0.8))
        progress(0.8, f"{pair.name}: geodesic distances for scoring")
        scorer = Scorer.build(mesh_N, truth)
        pool = CurvePool(mesh_M, mesh_N, truth)
        progress(1.0, f"{pair.name}: ready")
        return cls(pair, ShapePair(mesh_M, mesh_N, basis_M, basis_N), truth, pool, scorer)

    def score(self, C_NM: np.ndarray, seed: int) -> ErrorSummary:
        """Errors of a map solved from the curves of ``seed``, at the rows those curves did not use (all rows of a
        dense truth; the seed's held-out landmarks of a sparse one, as :func:`~curvefm.evaluation.protocol.scored_truth`
        selects them)."""
        held_out = self.pool.held_out(seed)
        rows = np.isin(self.scorer.rows_M, held_out) if len(held_out) else None
        return self.scorer(C_NM, self.shapes.basis_M, self.shapes.basis_N, rows)


@dataclass
class Scorer:
    rows_M: np.ndarray  # sampled ground-truth rows: source vertices...
    columns: np.ndarray  # ...and, for each, the row of `table` holding distances from its true partner
    table: np.ndarray  # (distinct partners, n_N) geodesic distances on the target
    diameter: float
    area: float

    @classmethod
    def build(cls, mesh_N: Mesh, truth: GroundTruth, max_rows: int = MAX_ROWS, seed: int = 0) -> Scorer:
        rows = np.arange(len(truth))
        if len(rows) > max_rows:
            rows = np.sort(np.random.default_rng(seed).choice(rows, max_rows, replace=False))
        partners, columns = np.unique(truth.ids_Y[rows], return_inverse=True)
        table = geodesic_distances(mesh_N, partners).astype(np.float32)
        return cls(truth.ids_X[rows], columns, table, geodesic_diameter(mesh_N), mesh_N.area)

    def __call__(
        self, C_NM: np.ndarray, basis_M: Basis, basis_N: Basis, rows: np.ndarray | None = None
    ) -> ErrorSummary:
        """Errors at the sampled rows, or at those of them ``rows`` (a mask over the sample) selects."""
        sources, columns = (self.rows_M, self.columns) if rows is None else (self.rows_M[rows], self.columns[rows])
        predicted = pointwise_from_fmap(C_NM, basis_N, basis_M, rows=sources)
        return ErrorSummary.from_distances(self.table[columns, predicted], self.diameter, self.area)
