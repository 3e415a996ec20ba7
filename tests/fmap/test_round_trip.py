"""The maps' round-trip quality (no ground truth): what it is on exact and empty maps, and that it improves as
correct curves are added on a real pair."""

import numpy as np
import pytest
from support.shapes import basis_of, ellipsoid

from curvefm.evaluation import ground_truth_curves, ground_truth_for
from curvefm.fmap import CurveMapSolver, RoundTripQuality
from curvefm.fmap.round_trip import CLEAR_OF_CURVES
from curvefm.geometry import build_mesh, load_mesh
from curvefm.store import Store


@pytest.fixture(scope="module")
def ellipsoid_pair():
    mesh = ellipsoid(12, 24)
    basis = basis_of(mesh, 20)
    return mesh, basis, RoundTripQuality(mesh, basis, mesh, basis)


def test_maps_that_are_exact_inverses_do_not_drift(ellipsoid_pair):
    mesh, basis, quality = ellipsoid_pair
    rotation = np.linalg.qr(np.random.default_rng(0).normal(size=(20, 20)))[0]  # any invertible pair will do
    found = quality.measure(rotation, rotation.T)
    assert found.target.shape == found.source.shape == (mesh.n_vertices,)
    assert found.target.dtype == np.float32
    assert found.score < 1e-5 and found.target.max() < 1e-5 and found.source.max() < 1e-5


def test_without_a_map_every_vertex_drifts_to_the_centroid(ellipsoid_pair):
    mesh, basis, quality = ellipsoid_pair
    found = quality.measure(np.zeros((20, 20)), np.zeros((20, 20)))
    unit = mesh.vertices / np.sqrt(mesh.area)
    centred = unit - basis.mass @ unit
    band_limited = basis.evecs @ basis.project(centred)  # the coordinates the drift is measured on
    np.testing.assert_allclose(found.target, np.linalg.norm(band_limited, axis=1), rtol=1e-4, atol=1e-6)
    assert found.target[found.worst_target] == found.target.max()  # the ellipsoid's symmetry makes ties
    assert found.score == pytest.approx(float(basis.mass @ found.target))


def test_where_to_click_next_keeps_clear_of_the_curves(ellipsoid_pair):
    """Without a map the tips of the ellipsoid's long axis drift furthest: a curve ending at one tip moves the
    hint to the furthest drifting vertex clear of it (the other tip); a shape without curves keeps its worst."""
    mesh, basis, quality = ellipsoid_pair
    maps = np.zeros((20, 20)), np.zeros((20, 20))
    tip = quality.measure(*maps).worst_target
    unit = mesh.vertices / np.sqrt(mesh.area)
    curve = np.argsort(np.linalg.norm(unit - unit[tip], axis=1))[:5]  # the tip and four vertices beside it
    found = quality.measure(*maps, curves_N=curve)
    clear = np.linalg.norm(unit[:, None] - unit[curve][None], axis=2).min(axis=1) > CLEAR_OF_CURVES
    assert not clear[tip] and clear.any() and not clear.all()
    assert clear[found.worst_target] and found.target[found.worst_target] == found.target[clear].max()
    length = np.ptp(unit, axis=0).max()
    assert np.linalg.norm(unit[found.worst_target] - unit[tip]) > 0.95 * length  # the other end of the ellipsoid
    assert found.worst_source == tip  # no curve on the source


def test_where_to_click_next_is_the_worst_vertex_when_curves_cover_the_shape(ellipsoid_pair):
    mesh, _, quality = ellipsoid_pair
    everywhere = np.arange(mesh.n_vertices)
    found = quality.measure(np.zeros((20, 20)), np.zeros((20, 20)), everywhere, everywhere)
    assert found.target[found.worst_target] == found.target.max()


def test_the_drift_does_not_depend_on_the_units_or_the_place_of_a_mesh(ellipsoid_pair):
    mesh, basis, quality = ellipsoid_pair
    moved = build_mesh(mesh.vertices * 7.0 + [3.0, -2.0, 5.0], mesh.faces)  # its unit-area basis is the same
    rng = np.random.default_rng(1)
    C_MN, C_NM = rng.normal(size=(20, 20)) / 5, rng.normal(size=(20, 20)) / 5
    here = quality.measure(C_MN, C_NM)
    there = RoundTripQuality(moved, basis, moved, basis).measure(C_MN, C_NM)
    np.testing.assert_allclose(there.target, here.target, rtol=1e-4, atol=1e-6)


def test_the_score_improves_as_correct_curves_are_added_on_faust(shared_data, tmp_path):
    source, target = shared_data / "faust/tr_reg_000.off", shared_data / "faust/tr_reg_011.off"
    mesh_M, mesh_N = load_mesh(source), load_mesh(target)
    truth = ground_truth_for(source, target, mesh_M, mesh_N)
    store = Store(tmp_path)
    basis_M, basis_N = store.ensure_basis(mesh_M, 120), store.ensure_basis(mesh_N, 120)
    quality = RoundTripQuality(mesh_M, basis_M, mesh_N, basis_N)
    scores, worst = {}, {}
    for count in (1, 5, 10):
        with CurveMapSolver(mesh_M.vertices, basis_M, mesh_N.vertices, basis_N) as solver:
            solver.add_curves([(a, b, 1.0) for a, b in ground_truth_curves(mesh_M, mesh_N, truth, count)])
            found = quality.measure(solver.C_MN, solver.C_NM)
        scores[count], worst[count] = found.score, found.target.max()
    assert scores[10] < scores[5] < scores[1], scores
    assert worst[10] < worst[1], worst
