"""The ground-truth protocol in both directions on real shapes (FAUST 000 -> 011): endpoints chosen on the source or
on the target, both maps scored, and never at the points the user gave."""

import numpy as np
import pytest

from curvefm import registry
from curvefm.errors import CurvefmError
from curvefm.evaluation import (
    ENDPOINT_SIDES,
    GroundTruth,
    evaluate_pair,
    ground_truth_curves,
    ground_truth_for,
    map_geodesic_errors,
    reversed_truth,
    score_maps,
    truth_to_score,
)
from curvefm.evaluation.protocol import held_out_landmarks, rows_to_score
from curvefm.evaluation.reproduce.datasets import Pair
from curvefm.evaluation.reproduce.scoring import DIRECTIONS, LoadedPair
from curvefm.fmap import Hints
from curvefm.geometry import load_mesh, shortest_path
from curvefm.matching import handed_out
from curvefm.pointwise import PointwiseMaps
from curvefm.progress import no_progress
from curvefm.store import Store

FAUST = Pair("faust", "faust/tr_reg_000.off", "faust/tr_reg_011.off")


@pytest.fixture(scope="module")
def faust(shared_data):
    M, N = load_mesh(shared_data / FAUST.source), load_mesh(shared_data / FAUST.target)
    return M, N, ground_truth_for(shared_data / FAUST.source, shared_data / FAUST.target, M, N)


def ends(curves, shape: int) -> list[int]:
    return [int(paths[shape][i]) for paths in curves for i in (0, -1)]


def test_endpoints_are_farthest_points_of_the_chosen_side_and_true_partners(faust):
    M, N, truth = faust
    partner = dict(zip(truth.ids_X.tolist(), truth.ids_Y.tolist(), strict=True))
    by_side = {side: ground_truth_curves(M, N, truth, 3, endpoints_on=side) for side in ENDPOINT_SIDES}
    for curves in by_side.values():
        assert [partner[v] for v in ends(curves, 0)] == ends(curves, 1)
    # farthest-point sampling starts at vertex 0 of the side the endpoints are chosen on, then spreads over it
    assert ends(by_side["source"], 0)[0] == 0 and ends(by_side["target"], 1)[0] == 0
    assert ends(by_side["source"], 0) != ends(by_side["target"], 0)
    with pytest.raises(CurvefmError, match="'source' or the 'target', not 'both'"):
        ground_truth_curves(M, N, truth, 3, endpoints_on="both")


@pytest.mark.parametrize("side", ENDPOINT_SIDES)
def test_the_user_points_are_never_scored(faust, side):
    M, N, truth = faust
    curves = ground_truth_curves(M, N, truth, 3, endpoints_on=side)
    given_M, given_N = ends(curves, 0), ends(curves, 1)
    sample = np.random.default_rng(0).choice(len(truth), 40, replace=False)
    rows = np.union1d(sample, np.flatnonzero(np.isin(truth.ids_X, given_M)))
    small = GroundTruth(truth.ids_X[rows], truth.ids_Y[rows], truth.kind, truth.dense)
    scored = truth_to_score(small, curves, 0, side)
    assert not set(scored.ids_X.tolist()) & set(given_M) and not set(scored.ids_Y.tolist()) & set(given_N)
    assert len(scored) == len(small) - len(set(given_M))
    # a map right at the user's points and wrong everywhere else: scored there, it would show a zero error
    p2p_MN = np.full(M.n_vertices, given_N[0])
    p2p_MN[given_M] = given_N
    assert map_geodesic_errors(p2p_MN, scored, N).min() > 0
    assert map_geodesic_errors(p2p_MN, small, N).min() == 0


def test_evaluate_scores_both_maps_from_endpoints_on_either_side(shared_data, tmp_path):
    reports = {
        side: evaluate_pair(
            shared_data / FAUST.source,
            shared_data / FAUST.target,
            n_curves=3,
            k=20,
            store=Store(tmp_path),
            method="curves",
            endpoints_on=side,
        )
        for side in ENDPOINT_SIDES
    }
    for side, report in reports.items():
        assert report["endpoints_on"] == side
        errors = report["errors"]
        assert set(errors) == set(DIRECTIONS.values())
        assert errors["source_to_target"]["count"] == errors["target_to_source"]["count"] < 6890 - 5
        assert all(0 < e["mean_area"] < 0.3 for e in errors.values())
    assert reports["source"]["errors"] != reports["target"]["errors"]


@pytest.fixture(scope="module")
def loaded(shared_data, tmp_path_factory):
    return LoadedPair.load(shared_data, FAUST, 20, Store(tmp_path_factory.mktemp("store")))


def sampled_curves(loaded: LoadedPair, side: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """Two curves whose endpoints are among the sampled rows, chosen on ``side``; as ``(path_M, path_N)``."""
    M, N, truth = loaded.shapes.mesh_M, loaded.shapes.mesh_N, loaded.truth
    mesh_from, mesh_to, rows = (M, N, truth) if side == "source" else (N, M, reversed_truth(truth))
    partner = dict(zip(rows.ids_X.tolist(), rows.ids_Y.tolist(), strict=True))
    ends = rows.ids_X[loaded.rows[[3, 50, 400, 900]]].tolist()
    paths = [
        (shortest_path(mesh_from.edge_graph, x, y), shortest_path(mesh_to.edge_graph, partner[x], partner[y]))
        for x, y in (ends[:2], ends[2:])
    ]
    return paths if side == "source" else [(path_M, path_N) for path_N, path_M in paths]


@pytest.mark.parametrize("side", ENDPOINT_SIDES)
def test_reproduce_scores_both_maps_away_from_the_user_points(loaded, side):
    truth = loaded.truth
    assert np.array_equal(truth.ids_X, np.arange(loaded.shapes.mesh_M.n_vertices))  # FAUST: identity
    curves = sampled_curves(loaded, side)
    given_M, given_N = ends(curves, 0), ends(curves, 1)
    # both maps right everywhere except at the points the user gave, where they are far off
    far_N, far_M = (
        int(np.argmax(np.linalg.norm(m.vertices - m.vertices[0], axis=1))) for m in loaded.shapes.meshes[::-1]
    )
    p2p_MN, p2p_NM = truth.ids_Y.copy(), truth.ids_X.copy()
    p2p_MN[given_M], p2p_NM[given_N] = far_N, far_M
    scored = loaded.score_pointwise(PointwiseMaps(p2p_NM=p2p_NM, p2p_MN=p2p_MN), side, 0, curves)
    assert set(scored) == set(DIRECTIONS.values())
    for errors in scored.values():
        assert errors.count == len(loaded.rows) - 4 == 996 and errors.mean == 0
    # scored at the user's points (no curves given), the same maps show their errors there, in each direction
    everywhere = loaded.score_pointwise(PointwiseMaps(p2p_NM=p2p_NM, p2p_MN=p2p_MN), side, 0, [])
    assert all(e.count == 1000 and e.mean > 0 for e in everywhere.values())
    # each direction scores its own map: spoil only the map target -> source away from the curves
    p2p_NM = np.roll(p2p_NM, 1)
    scored = loaded.score_pointwise(PointwiseMaps(p2p_NM=p2p_NM, p2p_MN=p2p_MN), side, 0, curves)
    assert scored["source_to_target"].mean == 0 and scored["target_to_source"].mean > 0


def test_reproduce_scores_the_maps_curvefm_match_hands_out(loaded):
    """The reproduce scorer's look-up gives what the product's scorer (``score_maps`` of ``handed_out``) gives at the
    same rows, both directions, endpoints on either side."""
    plugin, params = registry.load("method", "curves", None)
    sample = GroundTruth(loaded.truth.ids_X[loaded.rows], loaded.truth.ids_Y[loaded.rows], "identity", True)
    for side in ENDPOINT_SIDES:
        curves = loaded.pools[side].curves(5, 0, exact=False)
        fmaps = plugin.run(loaded.shapes, Hints.from_curves(curves), params, no_progress)
        ours = loaded.score_handed_out(fmaps, side, 0, curves)
        product = score_maps(loaded.shapes, handed_out(loaded.shapes, fmaps), truth_to_score(sample, curves, 0, side))
        for direction, errors in ours.items():
            assert errors.count == product[direction]["count"]
            assert errors.mean == pytest.approx(product[direction]["mean"], rel=1e-5)
            assert 0 < errors.mean_area < 0.3
        # handed out, not plain nearest neighbours in the embedding of one map: the figures differ
        assert ours["source_to_target"].mean != loaded.score(fmaps.C_NM, 0, curves).mean


@pytest.mark.parametrize("side", ENDPOINT_SIDES)
def test_a_landmark_truth_is_scored_at_the_held_out_landmarks_that_are_not_endpoints(faust, side):
    M, N, dense = faust
    landmarks = np.random.default_rng(1).choice(len(dense), 30, replace=False)
    truth = GroundTruth(dense.ids_X[landmarks], dense.ids_Y[landmarks], "landmarks", False)
    curves = ground_truth_curves(M, N, truth, 3, endpoints_on=side)
    keep = rows_to_score(truth, curves, 0, side)
    scored = truth_to_score(truth, curves, 0, side)
    assert np.array_equal(scored.ids_X, truth.ids_X[keep]) and np.array_equal(scored.ids_Y, truth.ids_Y[keep])
    held = held_out_landmarks(truth if side == "source" else reversed_truth(truth), 0)
    on_side = truth.ids_X if side == "source" else truth.ids_Y
    assert 0 < keep.sum() <= len(held) and set(on_side[keep].tolist()) <= set(held.tolist())
    assert not set(truth.ids_X[keep].tolist()) & set(ends(curves, 0))
    assert not set(truth.ids_Y[keep].tolist()) & set(ends(curves, 1))
