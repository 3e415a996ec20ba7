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
    truth_to_score,
)
from curvefm.evaluation.reproduce.datasets import Pair
from curvefm.evaluation.reproduce.scoring import DIRECTIONS, LoadedPair
from curvefm.fmap import Hints
from curvefm.geometry import load_mesh, shortest_path
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


def test_reproduce_scores_each_side_in_its_direction_away_from_the_curves(shared_data, tmp_path):
    loaded = LoadedPair.load(shared_data, FAUST, 20, Store(tmp_path))
    M, N, truth = loaded.shapes.mesh_M, loaded.shapes.mesh_N, loaded.truth
    plugin, params = registry.load("method", "curves", None)
    maps = plugin.run(loaded.shapes, Hints.from_curves(loaded.pool.curves(5, 0, exact=False)), params, no_progress)
    for side, scorer in loaded.scorers.items():
        # two curves whose endpoints are among the sampled rows, on the side the rows start from
        mesh_from, mesh_to, rows = (M, N, truth) if side == "source" else (N, M, reversed_truth(truth))
        partner = dict(zip(rows.ids_X.tolist(), rows.ids_Y.tolist(), strict=True))
        ends = scorer.rows_from[:4].tolist()
        paths = [
            (shortest_path(mesh_from.edge_graph, x, y), shortest_path(mesh_to.edge_graph, partner[x], partner[y]))
            for x, y in (ends[:2], ends[2:])
        ]
        curves = paths if side == "source" else [(path_M, path_N) for path_N, path_M in paths]
        assert loaded.score_side(maps, side, 0, []).count == len(scorer.rows_from) == 1000
        away = loaded.score_side(maps, side, 0, curves)
        assert away.count == 996 and 0 < away.mean_area < 0.3
