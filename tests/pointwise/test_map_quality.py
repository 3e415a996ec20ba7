"""Intrinsic quality figures of pointwise maps and the user's curves as pins (no ground truth needed)."""

import numpy as np
import pytest
from support.shapes import stretched_ellipsoid_pair

from curvefm.geometry import shortest_path
from curvefm.pointwise import CurvePins, PointwiseMaps, compare, measure
from curvefm.pointwise.curve_pins import FREE
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
    return PointwiseMaps(
        rng.integers(0, pair.mesh_M.n_vertices, pair.mesh_N.n_vertices),
        rng.integers(0, pair.mesh_N.n_vertices, pair.mesh_M.n_vertices),
    )


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
    assert {w.split()[0] for w in worse} == {"coverage", "round_trip", "inverse_deviation"}  # the residual: reported
    assert compare(good, bad) == [] and compare(good, good) == []


def test_without_curves_there_is_no_curve_residual(pair):
    assert measure(pair, identity(pair)).curve_residual is None


def test_only_the_curves_ends_are_hard_pins_and_their_interiors_soft_partners_by_arc_length(pair, curves):
    pair = ShapePair(pair.mesh_M, pair.mesh_M, pair.basis_M, pair.basis_M)  # same arc lengths on both sides
    path = curves[0][0]
    reversed_pins = CurvePins.from_curves(pair.mesh_M, pair.mesh_N, [(path, path[::-1])])
    assert reversed_pins.M_to_N[path[0]] == path[-1] and reversed_pins.M_to_N[path[-1]] == path[0]
    pins = CurvePins.from_curves(pair.mesh_M, pair.mesh_N, curves)
    ends = np.unique([p[i] for p, _ in curves for i in (0, -1)])
    np.testing.assert_array_equal(np.flatnonzero(pins.M_to_N != FREE), ends)  # the points the user gave
    np.testing.assert_array_equal(np.flatnonzero(pins.N_to_M != FREE), ends)
    pinned = pins.pin_MN(scrambled(pair).p2p_MN)
    np.testing.assert_array_equal(pinned[ends], ends)
    off = np.setdiff1d(np.arange(pair.mesh_M.n_vertices), ends)
    np.testing.assert_array_equal(pinned[off], scrambled(pair).p2p_MN[off])
    inner = np.setdiff1d(np.concatenate([p for p, _ in curves]), ends)
    np.testing.assert_array_equal(np.flatnonzero(pins.along_M_to_N != FREE), inner)
    np.testing.assert_array_equal(pins.along_MN(scrambled(pair).p2p_MN)[inner], inner)  # identical curves
    rows = np.array([ends[0], off[0]])
    np.testing.assert_array_equal(pins.pin_NM(np.array([7, 7]), rows), [ends[0], 7])
    every = CurvePins.from_curves(pair.mesh_M, pair.mesh_N, curves, hard_interiors=True)  # paths known to match
    hard = every.pin_MN(scrambled(pair).p2p_MN), every.pin_NM(scrambled(pair).p2p_NM)
    assert (every.along_M_to_N == FREE).all() and measure(
        pair, PointwiseMaps(hard[1], hard[0]), curves
    ).curve_residual == 0


def test_the_curve_residual_and_round_trip_leave_out_the_curves_ends(pair, curves):
    """A map wrong only at the curves' ends (where refiners pin it) scores as the perfect map does."""
    same = ShapePair(pair.mesh_M, pair.mesh_M, pair.basis_M, pair.basis_M)
    elsewhere = np.setdiff1d(np.arange(same.mesh_M.n_vertices), np.concatenate([p for p, _ in curves]))[0]
    wrong_at_ends = identity(same)
    ends = np.unique([p[i] for p, _ in curves for i in (0, -1)])
    wrong_at_ends.p2p_MN[ends] = wrong_at_ends.p2p_NM[ends] = elsewhere
    quality = measure(same, wrong_at_ends, curves)
    assert quality.curve_residual == 0 and quality.round_trip == 0
    wrong_inside = identity(same)
    wrong_inside.p2p_MN[curves[0][0][1:-1]] = wrong_inside.p2p_NM[curves[0][0][1:-1]] = elsewhere
    quality = measure(same, wrong_inside, curves)
    assert quality.curve_residual > 0 and quality.round_trip > 0
