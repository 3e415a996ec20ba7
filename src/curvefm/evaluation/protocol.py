"""Curves and scores from ground truth: the protocol of the accuracy tests, ``curvefm evaluate``, the
benchmarks and ``curvefm reproduce``.

A source curve is the geodesic path between two endpoints with a known partner. Its target curve is either
*traced* (the geodesic path between the ground-truth images of the endpoints, what a user clicking both ends
gets) or *exact* (the source path carried vertex by vertex through a dense ground truth, the paper's
"pre-labelled" curves). :func:`ground_truth_curves` is the fixed protocol of the tests (2 x n farthest points
paired in sampling order); :class:`CurvePool` draws seeded random subsets for the curve-count sweeps.

Both take the side the endpoints are chosen on (``endpoints_on``, one of :data:`ENDPOINT_SIDES`): on the source,
the target endpoints are their true images; on the target, the other way round. A map is scored both ways
(:func:`score`), and never at the points the user gave (:func:`truth_to_score`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from curvefm.errors import InvalidInput
from curvefm.evaluation.ground_truth import GroundTruth, ground_truth_for
from curvefm.evaluation.metrics import evaluate_map
from curvefm.fmap import DEFAULT_K
from curvefm.geometry import Mesh, farthest_point_sampling, load_mesh, shortest_path
from curvefm.matching import MatchResult, match
from curvefm.pointwise import PointwiseMaps
from curvefm.progress import Progress, no_progress
from curvefm.spectral import ShapePair
from curvefm.store import Store

HELD_OUT_FOLDS = 3
"""A sparse ground truth's landmarks are cut into this many folds; each seed scores the maps at one of them and
draws its curves' endpoints from the others."""
HELD_OUT_STREAM = 7  # seeds the landmarks' shuffle apart from the endpoints' draws
Curves = Sequence[tuple[np.ndarray, np.ndarray]]
"""Corresponding ``(path_M, path_N)`` vertex paths."""
DIRECTIONS = ("source_to_target", "target_to_source")
"""The pointwise maps a match scores."""
ENDPOINT_SIDES = ("source", "target")
"""Where a protocol chooses the curves' endpoints; their partners on the other shape come from the ground truth."""


def reversed_truth(truth: GroundTruth) -> GroundTruth:
    """The same correspondences read from Y to X."""
    return GroundTruth(truth.ids_Y, truth.ids_X, truth.kind, truth.dense)


def checked_side(endpoints_on: str) -> str:
    if endpoints_on not in ENDPOINT_SIDES:
        raise InvalidInput(f"endpoints are chosen on the 'source' or the 'target', not '{endpoints_on}'")
    return endpoints_on


def swapped(curves: Curves) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(path_N, path_M)`` pairs as ``(path_M, path_N)``, and back."""
    return [(b, a) for a, b in curves]


def ground_truth_curves(
    mesh_M: Mesh,
    mesh_N: Mesh,
    truth: GroundTruth,
    n_curves: int,
    seed_vertex: int = 0,
    endpoints_on: str = "source",
) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n_curves`` pairs ``(path_M, path_N)`` of corresponding vertex paths (internal ids) built from the ground
    truth, their endpoints 2 x ``n_curves`` farthest points of the ``endpoints_on`` side. A sparse ground truth's
    endpoints avoid the landmarks :func:`held_out_landmarks` keeps for scoring (seed 0)."""
    if checked_side(endpoints_on) == "target":
        return swapped(ground_truth_curves(mesh_N, mesh_M, reversed_truth(truth), n_curves, seed_vertex))
    partner = dict(zip(truth.ids_X.tolist(), truth.ids_Y.tolist(), strict=True))
    known = np.fromiter(partner, dtype=np.int64)
    known = known[~np.isin(known, held_out_landmarks(truth, 0))]
    if len(known) < 2 * n_curves:
        held = "" if truth.dense else " (the others are held out to score the map at)"
        raise InvalidInput(f"{len(known)} known correspondences{held} cannot give {n_curves} curves")
    endpoints = []
    for vertex in farthest_point_sampling(mesh_M, 2 * n_curves, seed_vertex):
        if vertex not in partner:  # sparse truth: snap to the nearest vertex that has a partner
            vertex = known[np.argmin(np.linalg.norm(mesh_M.vertices[known] - mesh_M.vertices[vertex], axis=1))]
        endpoints.append(int(vertex))
    curves = []
    for a, b in zip(endpoints[0::2], endpoints[1::2], strict=True):
        curves.append(
            (
                shortest_path(mesh_M.edge_graph, a, b),
                shortest_path(mesh_N.edge_graph, partner[a], partner[b]),
            )
        )
    return curves


def held_out_landmarks(truth: GroundTruth, seed: int) -> np.ndarray:
    """The source vertices of a sparse ground truth that the curves of ``seed`` avoid and the maps are scored at
    (empty for a dense one). The landmarks are shuffled once and cut into ``HELD_OUT_FOLDS`` folds; seed s holds out
    fold s mod ``HELD_OUT_FOLDS``, so every run of that many seeds scores every landmark once."""
    if truth.dense:
        return np.zeros(0, dtype=np.int64)
    order = np.random.default_rng(HELD_OUT_STREAM).permutation(distinct_sources(truth))
    return np.sort(np.array_split(order, HELD_OUT_FOLDS)[seed % HELD_OUT_FOLDS])


def scored_truth(truth: GroundTruth, seed: int, endpoints_on: str = "source") -> GroundTruth:
    """The rows a map solved from the curves of ``seed`` (endpoints chosen on ``endpoints_on``) may be scored on: all
    of a dense truth, the :func:`held_out_landmarks` of a sparse one."""
    return subset(truth, held_out_rows(truth, seed, endpoints_on))


def held_out_rows(truth: GroundTruth, seed: int, endpoints_on: str = "source") -> np.ndarray:
    """A mask over ``truth``'s rows: those of :func:`scored_truth`."""
    if truth.dense:
        return np.ones(len(truth), dtype=bool)
    if checked_side(endpoints_on) == "target":
        return np.isin(truth.ids_Y, held_out_landmarks(reversed_truth(truth), seed))
    return np.isin(truth.ids_X, held_out_landmarks(truth, seed))


def subset(truth: GroundTruth, rows: np.ndarray) -> GroundTruth:
    """The rows of ``truth`` that the mask ``rows`` selects."""
    return GroundTruth(truth.ids_X[rows], truth.ids_Y[rows], truth.kind, truth.dense)


def curve_ends(curves: Curves) -> tuple[np.ndarray, np.ndarray]:
    """The vertices the curves ``(path_M, path_N)`` end at: on M, and on N."""
    ends = np.array([[path[0], path[-1]] for pair in curves for path in pair], dtype=np.int64).reshape(-1, 2, 2)
    return ends[:, 0].ravel(), ends[:, 1].ravel()


def rows_away_from_ends(truth: GroundTruth, curves: Curves) -> np.ndarray:
    """A mask over ``truth``'s rows: those of :func:`truth_away_from_ends`."""
    ends_M, ends_N = curve_ends(curves)
    return ~np.isin(truth.ids_X, ends_M) & ~np.isin(truth.ids_Y, ends_N)


def truth_away_from_ends(truth: GroundTruth, curves: Curves) -> GroundTruth:
    """The ground-truth rows at neither end of any curve (on either shape): the points the user gave, which the
    refiners pin, say nothing about the map."""
    return subset(truth, rows_away_from_ends(truth, curves))


def rows_to_score(truth: GroundTruth, curves: Curves, seed: int = 0, endpoints_on: str = "source") -> np.ndarray:
    """A mask over ``truth``'s rows: those of :func:`truth_to_score`, for scorers that look distances up by row
    (``curvefm reproduce``'s)."""
    return held_out_rows(truth, seed, endpoints_on) & rows_away_from_ends(truth, curves)


def truth_to_score(truth: GroundTruth, curves: Curves, seed: int = 0, endpoints_on: str = "source") -> GroundTruth:
    """The rows a map solved from ``curves`` (drawn for ``seed`` on the ``endpoints_on`` side) is scored on:
    :func:`scored_truth` without the curves' ends (:func:`truth_away_from_ends`)."""
    return subset(truth, rows_to_score(truth, curves, seed, endpoints_on))


def distinct_sources(truth: GroundTruth) -> np.ndarray:
    """The ground truth's source vertices, each once, in the order of its rows."""
    return np.array(list(dict.fromkeys(truth.ids_X.tolist())), dtype=np.int64)


class CurvePool:
    """Candidate endpoints on the source and their partners, from which seeded random curves are drawn.

    With dense ground truth the candidates are ``size`` farthest points (snapped to vertices with a partner), a
    few among the thousand rows a map is scored on. With sparse ground truth (landmarks) each seed holds out a
    fold of the landmarks for scoring (:meth:`held_out`) and draws endpoints from the rest: with 21 landmarks, 20
    curves would otherwise end at nearly all of them, and a map would be scored on the very points it was given.
    A subset of n curves is n distinct unordered pairs of candidates, so curves may share an endpoint, as clicked
    curves often do.

    With ``endpoints_on="target"`` the candidates are the target's (the pool works on the swapped pair, so
    :meth:`held_out`, :meth:`candidates` and :meth:`endpoints` name target vertices) and :meth:`curves` still
    returns ``(path_M, path_N)``.
    """

    def __init__(self, mesh_M: Mesh, mesh_N: Mesh, truth: GroundTruth, size: int = 40, endpoints_on: str = "source"):
        self.endpoints_on = checked_side(endpoints_on)
        if endpoints_on == "target":
            mesh_M, mesh_N, truth = mesh_N, mesh_M, reversed_truth(truth)
        self.mesh_M, self.mesh_N, self.truth = mesh_M, mesh_N, truth
        self.partner = dict(zip(truth.ids_X.tolist(), truth.ids_Y.tolist(), strict=True))
        if truth.dense:
            known = np.fromiter(self.partner, dtype=np.int64)
            samples = farthest_point_sampling(mesh_M, size)
            nearest = [
                known[np.argmin(np.linalg.norm(mesh_M.vertices[known] - mesh_M.vertices[v], axis=1))] for v in samples
            ]
            self.landmarks = np.array(list(dict.fromkeys(int(v) for v in nearest)), dtype=np.int64)
        else:
            self.landmarks = distinct_sources(truth)

    def held_out(self, seed: int) -> np.ndarray:
        """Source vertices kept from the curves of this seed, to score the maps at (:func:`held_out_landmarks`)."""
        return held_out_landmarks(self.truth, seed)

    def candidates(self, seed: int) -> np.ndarray:
        """The endpoints the curves of this seed are drawn from."""
        return self.landmarks[~np.isin(self.landmarks, self.held_out(seed))]

    @property
    def max_curves(self) -> int:
        """The most distinct curves every seed can draw."""
        n = min(len(self.candidates(seed)) for seed in range(HELD_OUT_FOLDS))
        return n * (n - 1) // 2

    def endpoints(self, count: int, seed: int) -> list[tuple[int, int]]:
        """``count`` distinct candidate pairs (source vertex ids), the same for the same seed."""
        if count > self.max_curves:
            raise InvalidInput(f"{self.max_curves} candidate endpoint pairs cannot give {count} distinct curves")
        candidates = self.candidates(seed)
        rng = np.random.default_rng(seed)
        chosen: dict[tuple[int, int], None] = {}
        while len(chosen) < count:
            a, b = rng.choice(len(candidates), size=2, replace=False)
            chosen[(int(candidates[min(a, b)]), int(candidates[max(a, b)]))] = None
        return list(chosen)

    def curves(self, count: int, seed: int, exact: bool) -> list[tuple[np.ndarray, np.ndarray]]:
        """Corresponding ``(path_M, path_N)`` pairs: the other side's curves traced, or exact ones (dense truth
        only)."""
        if exact and not self.truth.dense:
            raise InvalidInput(f"exact curves need a dense ground truth; '{self.truth.kind}' is sparse")
        out = []
        for a, b in self.endpoints(count, seed):
            path_M = shortest_path(self.mesh_M.edge_graph, a, b)
            if exact:
                path_N = carried_path(self.mesh_N, path_M, self.partner)
            else:
                path_N = shortest_path(self.mesh_N.edge_graph, self.partner[a], self.partner[b])
            out.append((path_M, path_N))
        return swapped(out) if self.endpoints_on == "target" else out


def carried_path(mesh_N: Mesh, path_M: np.ndarray, partner: dict[int, int]) -> np.ndarray:
    """The image of a source path through the ground truth, as an edge path on N.

    Vertices without a partner are skipped; where consecutive images do not share an edge (a remeshed
    target, or an approximate ground truth) the gap is closed with the shortest path between them.
    """
    partners = [partner[int(v)] for v in path_M if int(v) in partner]
    partners = [v for i, v in enumerate(partners) if i == 0 or v != partners[i - 1]]
    if len(partners) < 2:
        raise InvalidInput("the ground truth maps the whole curve to a single vertex")
    images = np.array(partners, dtype=np.int64)
    adjacent = np.asarray(mesh_N.edge_graph[images[:-1], images[1:]]).ravel() > 0
    path = [images[:1]]
    for i, (a, b) in enumerate(zip(images[:-1], images[1:], strict=True)):
        path.append(images[i + 1 : i + 2] if adjacent[i] else shortest_path(mesh_N.edge_graph, a, b)[1:])
    return np.concatenate(path)


def score(result: MatchResult, truth: GroundTruth) -> dict[str, Any]:
    """Errors of both pointwise maps: source -> target measured on the target, and the reverse."""
    return score_maps(result.pair, result.maps, truth)


def score_maps(
    pair: ShapePair, maps: PointwiseMaps, truth: GroundTruth, directions: Sequence[str] = DIRECTIONS
) -> dict[str, Any]:
    """Errors of ``pair``'s pointwise ``maps`` in each of ``directions``: source -> target measured on the target,
    target -> source on the source."""
    scored = {
        "source_to_target": lambda: evaluate_map(maps.p2p_MN, truth, pair.mesh_N),
        "target_to_source": lambda: evaluate_map(maps.p2p_NM, (truth.ids_Y, truth.ids_X), pair.mesh_M),
    }
    return {direction: scored[direction]().as_dict() for direction in directions}


def evaluate_pair(
    source: str | Path,
    target: str | Path,
    n_curves: int = 10,
    k: int = DEFAULT_K,
    alpha: float | None = None,
    store: Store | None = None,
    progress: Progress = no_progress,
    method: str = "combined",
    method_params: dict[str, Any] | None = None,
    endpoints_on: str = "source",
) -> dict[str, Any]:
    """Match a pair with known ground truth using curves from that truth, their endpoints chosen on the
    ``endpoints_on`` side (``method``: any map method; the descriptor baselines get the curves' endpoints as
    landmarks), and score both maps away from the curves' ends (:func:`truth_to_score`)."""
    mesh_M, mesh_N = load_mesh(source), load_mesh(target)
    truth = ground_truth_for(source, target, mesh_M, mesh_N)
    curves = ground_truth_curves(mesh_M, mesh_N, truth, n_curves, endpoints_on=endpoints_on)
    result = match(
        mesh_M,
        mesh_N,
        curves,
        k=k,
        alpha=alpha,
        store=store,
        progress=progress,
        method=method,
        method_params=method_params,
    )
    scored = truth_to_score(truth, curves, 0, endpoints_on)
    held = "rows" if truth.dense else "landmarks the curves were not drawn from"
    return {
        "source": str(source),
        "target": str(target),
        "ground_truth": truth.kind,
        "endpoints_on": endpoints_on,
        "scored_at": f"{len(scored)} {held}, none at a curve's end",
        "method": method,
        "curves": n_curves,
        "k": k,
        "alpha": alpha,
        "errors": score(result, scored),
    }
