"""The suggested next curve: ends far from the curves where the maps drift, their images through the maps."""

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra
from support.shapes import stretched_ellipsoid_pair

from curvefm.evaluation import faust5k_truth
from curvefm.fmap import RoundTripQuality
from curvefm.geometry import load_mesh, shortest_path
from curvefm.pointwise import fmap_from_pointwise, suggest_curve
from curvefm.spectral import ShapePair, laplace_beltrami_basis

K = 20


@pytest.fixture(scope="module")
def pair() -> ShapePair:
    M, bM, N, bN = stretched_ellipsoid_pair()  # same connectivity: vertex i <-> vertex i
    return ShapePair(M, N, bM, bN)


@pytest.fixture(scope="module")
def maps(pair):
    """The functional maps the identity induces, both ways."""
    identity = np.arange(pair.mesh_M.n_vertices)
    return (
        fmap_from_pointwise(identity, pair.basis_M, pair.basis_N, K, K),
        fmap_from_pointwise(identity, pair.basis_N, pair.basis_M, K, K),
    )


def distances(pair, sources) -> np.ndarray:
    return dijkstra(pair.mesh_M.edge_graph, indices=np.unique(sources), min_only=True)


def test_with_even_drift_the_ends_are_the_farthest_points_from_the_curves(pair, maps):
    curve = shortest_path(pair.mesh_M.edge_graph, 0, 600)
    found = suggest_curve(pair, *maps, np.ones(pair.mesh_M.n_vertices), curve)
    start, end = found.source
    from_curve = distances(pair, curve)
    assert from_curve[start] == pytest.approx(from_curve.max())
    from_both = np.minimum(from_curve, distances(pair, [start]))
    assert from_both[end] == pytest.approx(from_both.max()) and from_both[end] > 0


def test_drift_draws_the_start_to_where_the_maps_disagree(pair, maps):
    curve = shortest_path(pair.mesh_M.edge_graph, 0, 600)
    from_curve = distances(pair, curve)
    drift = np.full(pair.mesh_M.n_vertices, 1e-3)
    uncertain = int(np.argsort(from_curve)[len(from_curve) // 2])  # halfway out, not the farthest
    drift[uncertain] = 1.0
    assert suggest_curve(pair, *maps, drift, curve).source[0] == uncertain


def test_the_images_are_where_the_maps_send_the_ends(pair, maps):
    found = suggest_curve(pair, *maps, np.ones(pair.mesh_M.n_vertices), np.zeros(0, dtype=np.int64))
    # the identity's maps send each end near itself (same connectivity); a wrong direction would not
    scale = np.sqrt(pair.mesh_N.area)
    for source, target in zip(found.source, found.target, strict=True):
        apart = dijkstra(pair.mesh_N.edge_graph, indices=source)[target] / scale
        assert apart < 0.1


def test_the_first_curve_does_not_join_mirror_twins_on_faust(shared_data):
    """From no curve (a new session's zero maps) the suggested ends must not be each other's mirror images: FAUST's
    two feet gave a curve the left-right mirror maps onto itself, and a flipped map. FAUST-5k's symmetric ground
    truth gives each vertex's mirror partner."""
    path = shared_data / "faust_5k_bcicp/tr_reg_000.off"
    mesh = load_mesh(path)
    pair = ShapePair(mesh, mesh, *(2 * [laplace_beltrami_basis(mesh, 60)]))
    zero = np.zeros((60, 60))
    drift = RoundTripQuality(mesh, pair.basis_M, mesh, pair.basis_N).measure(zero, zero).source
    start, end = suggest_curve(pair, zero, zero, drift, np.zeros(0, dtype=np.int64)).source
    truth, mirror = (faust5k_truth(path, path, mesh, mesh, symmetric=flag) for flag in (False, True))
    assert np.array_equal(truth.ids_X, mirror.ids_X)
    rows = truth.ids_X  # the rows of the ground truth nearest the ends: their mirror partners are known
    twin_of_start = mirror.ids_Y[np.argmin(np.linalg.norm(mesh.vertices[rows] - mesh.vertices[start], axis=1))]
    apart = dijkstra(mesh.edge_graph, indices=end)
    scale = np.sqrt(mesh.area)
    assert apart[twin_of_start] / scale > 0.5  # a foot and the other foot would be a few edges apart
    assert apart[start] / scale > 0.5  # and the curve is long: it spans the shape


def test_zero_maps_and_no_drift_never_give_a_curve_of_no_length(pair):
    """Zero maps send every vertex to one target vertex, and no drift leaves nothing to maximise: the ends must
    still be two vertices on each shape (the benchmark's simulated person crashed on a curve of one vertex)."""
    zero = np.zeros((K, K))
    for drift in (np.zeros(pair.mesh_M.n_vertices), np.ones(pair.mesh_M.n_vertices)):
        found = suggest_curve(pair, zero, zero, drift, np.zeros(0, dtype=np.int64))
        assert found.source[0] != found.source[1]
        assert found.target[0] != found.target[1]
        # the moved image is the farthest from the other, not merely next to it
        apart = dijkstra(pair.mesh_N.edge_graph, indices=found.target[0])
        assert apart[found.target[1]] == pytest.approx(apart.max())
