"""Curves and scores from ground truth: the protocol of the accuracy tests, ``curvefm evaluate`` and the
benchmarks.

Curve endpoints are 2 x n farthest points on the source (restricted to vertices with a known partner),
paired in sampling order; a source curve is the geodesic path between its endpoints and its target curve
is the geodesic path between the ground-truth images of those endpoints ("traced" curves in the paper).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from curvefm.errors import CurvefmError
from curvefm.evaluation import GroundTruth, evaluate_map, farthest_point_sampling, ground_truth_for
from curvefm.matching import MatchResult, match
from curvefm.mesh import Mesh, load_mesh
from curvefm.paths import shortest_path
from curvefm.progress import Progress, no_progress
from curvefm.solver import DEFAULT_ALPHA, DEFAULT_K
from curvefm.store import Store


def ground_truth_curves(
    mesh_M: Mesh, mesh_N: Mesh, truth: GroundTruth, n_curves: int, seed_vertex: int = 0
) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n_curves`` pairs of corresponding vertex paths (internal ids) built from the ground truth."""
    partner = dict(zip(truth.ids_X.tolist(), truth.ids_Y.tolist(), strict=True))
    known = np.fromiter(partner, dtype=np.int64)
    if len(known) < 2 * n_curves:
        raise CurvefmError(f"{len(known)} known correspondences cannot give {n_curves} curves")
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


def score(result: MatchResult, truth: GroundTruth) -> dict:
    """Errors of both pointwise maps: source -> target measured on the target, and the reverse."""
    reverse = (truth.ids_Y, truth.ids_X)
    return {
        "source_to_target": evaluate_map(result.maps.p2p_MN, truth, result.mesh_N).as_dict(),
        "target_to_source": evaluate_map(result.maps.p2p_NM, reverse, result.mesh_M).as_dict(),
    }


def evaluate_pair(
    source: str | Path,
    target: str | Path,
    n_curves: int = 10,
    k: int = DEFAULT_K,
    alpha: float = DEFAULT_ALPHA,
    store: Store | None = None,
    progress: Progress = no_progress,
) -> dict:
    """Match a pair with known ground truth using curves from that truth, and score it."""
    mesh_M, mesh_N = load_mesh(source), load_mesh(target)
    truth = ground_truth_for(source, target, mesh_M, mesh_N)
    curves = ground_truth_curves(mesh_M, mesh_N, truth, n_curves)
    result = match(mesh_M, mesh_N, curves, k=k, alpha=alpha, store=store, progress=progress)
    return {
        "source": str(source),
        "target": str(target),
        "ground_truth": truth.kind,
        "curves": n_curves,
        "k": k,
        "alpha": alpha,
        "errors": score(result, truth),
    }
