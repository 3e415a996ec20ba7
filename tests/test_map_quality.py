"""Intrinsic quality figures of pointwise maps and the user's curves as pins (no ground truth needed)."""

import numpy as np
import pytest
from shapes import stretched_ellipsoid_pair

from curvefm.geometry import shortest_path
from curvefm.pointwise import CurvePins, PointwiseMaps, compare, measure
from curvefm.spectral import ShapePair


@pytest.fixture(scope="module")
def pair() -> ShapePair:
    M, bM, N, bN = stretched_ellipsoid_pair()  # same connectivity: vertex i <-> vertex i
    return ShapePair(M, N, bM, bN)


@pytest.fixture(scope="module")
def curves(pair):
    paths = [shortest_path(pair.mesh_M.edge_graph, a, b) for a, b in ((0, 600), (100, 900))]
    return [(p, p) for p in paths]


def identity(pair) -> PointwiseMaps:
    return PointwiseMaps(np.arange(pair.mesh_N.n_vertices), np.arange(pair.mesh_M.n_vertices))


def scrambled(pair, seed=0) -> PointwiseMaps:
    rng = np.random.default_rng(seed)
    return PointwiseMaps(rng.integers(0, pair.mesh_M.n_vertices, pair.mesh_N.n_vertices),
                         rng.integers(0, pair.mesh_N.n_vertices, pair.mesh_M.n_vertices))  # fmt: skip


def test_a_perfect_map_scores_perfectly(pair, curves):
    same = ShapePair(pair.mesh_M, pair.mesh_M, pair.basis_M, pair.basis_M)
    quality = measure(same, identity(same), curves)
    assert quality.curve_residual == 0 and quality.round_trip == 0
    assert quality.coverage == pytest.approx(1.0)
    assert quality.inverse_deviation < 1e-8
    # to a stretched copy the true map is still bijective; its induced functional maps are nearly inverse
    stretched = measure(pair, identity(pair), curves)
    assert stretched.round_trip == 0 and stretched.inverse_deviation < 0.05


def test_a_scrambled_map_scores_badly_on_every_figure(pair, curves):
    good, bad = measure(pair, identity(pair), curves), measure(pair, scrambled(pair), curves)
    assert bad.curve_residual > 0.1 and bad.round_trip > 0.1
    assert bad.coverage < 0.8 and bad.inverse_deviation > 0.5
    worse = compare(bad, good)
    assert {w.split()[0] for w in worse} == {"curve_residual", "coverage", "round_trip", "inverse_deviation"}
    assert compare(good, bad) == [] and compare(good, good) == []


def test_without_curves_there_is_no_curve_residual(pair):
    assert measure(pair, identity(pair)).curve_residual is None


def test_pins_send_each_curve_onto_its_partner_by_arc_length(pair, curves):
    pair = ShapePair(pair.mesh_M, pair.mesh_M, pair.basis_M, pair.basis_M)  # same arc lengths on both sides
    path = curves[0][0]
    reversed_pins = CurvePins.from_curves(pair.mesh_M, pair.mesh_N, [(path, path[::-1])])
    assert reversed_pins.M_to_N[path[0]] == path[-1] and reversed_pins.M_to_N[path[-1]] == path[0]
    pins = CurvePins.from_curves(pair.mesh_M, pair.mesh_N, curves)
    pinned = pins.pin_MN(scrambled(pair).p2p_MN)
    on_curves = np.unique(np.concatenate([p for p, _ in curves]))
    np.testing.assert_array_equal(pinned[on_curves], on_curves)  # identical curves: each vertex to itself
    off = np.setdiff1d(np.arange(pair.mesh_M.n_vertices), on_curves)
    np.testing.assert_array_equal(pinned[off], scrambled(pair).p2p_MN[off])
    rows = np.array([on_curves[0], off[0]])
    np.testing.assert_array_equal(pins.pin_NM(np.array([7, 7]), rows), [on_curves[0], 7])
    assert measure(pair, PointwiseMaps(pins.pin_NM(scrambled(pair).p2p_NM), pinned), curves).curve_residual == 0
