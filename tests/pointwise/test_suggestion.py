"""The suggested next curve: ends far from the curves where the maps drift, their images through the maps."""

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra
from support.shapes import stretched_ellipsoid_pair

from curvefm.geometry import shortest_path
from curvefm.pointwise import fmap_from_pointwise, suggest_curve
from curvefm.spectral import ShapePair

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
