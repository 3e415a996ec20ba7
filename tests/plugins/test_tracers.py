"""Tracer plugins: path validity, geodesic optimality, feature following, scale invariance, bad input."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.sparse.csgraph import dijkstra

from curvefm import registry
from curvefm.errors import CurvefmError
from curvefm.geometry import DisplayMesh, build_mesh, check_edge_path, display_mesh, load_mesh
from curvefm.plugins import tracers
from curvefm.plugins.tracers import ANISOTROPIC, GEODESIC
from curvefm.session import trace_curve

GEODESIC_DEFAULTS = GEODESIC.parse_params({})
ANISOTROPIC_DEFAULTS = ANISOTROPIC.parse_params({})


def grid_faces(nu: int, nv: int, wrap_u: bool = False) -> np.ndarray:
    idx = np.arange(nu * nv).reshape(nu, nv)
    if wrap_u:
        idx = np.r_[idx, idx[:1]]
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return np.r_[np.c_[a, b, c], np.c_[a, c, d]]


def roof(slope: float = 1.0, nx: int = 61, ny: int = 31, length: float = 12.0, half_width: float = 3.0, seed=0):
    """A roof z = -slope * |y| with a sharp straight crest along the x axis (a valley for slope < 0).

    Vertices are jittered (except across the crest, which stays the straight line y = 0 made of mesh edges) so
    Dijkstra has no exact ties. Returns the mesh, each vertex's distance to the crest line and ``ny``.
    """
    rng = np.random.default_rng(seed)
    x, y = np.linspace(0, length, nx), np.linspace(-half_width, half_width, ny)
    X, Y = np.meshgrid(x, y, indexing="ij")
    X = X + 0.25 * (x[1] - x[0]) * rng.uniform(-1, 1, X.shape)
    Y = Y + 0.25 * (y[1] - y[0]) * rng.uniform(-1, 1, X.shape) * (np.abs(Y) > 1e-12)
    mesh = build_mesh(np.c_[X.ravel(), Y.ravel(), -slope * np.abs(Y.ravel())], grid_faces(nx, ny), name="roof")
    return mesh, np.abs(Y.ravel()), ny


def edge_length(mesh, path) -> float:
    return float(np.linalg.norm(np.diff(mesh.vertices[path], axis=0), axis=1).sum())


@pytest.fixture(scope="module")
def wolf(shared_data):
    return load_mesh(shared_data / "tosca" / "wolf0.off")


# ----------------------------------------------------------------------------------------------------------


def test_registered_through_entry_points():
    assert {"geodesic", "anisotropic"} <= set(registry.names("tracer"))
    assert registry.get("tracer", "geodesic") is GEODESIC
    assert registry.get("tracer", "anisotropic") is ANISOTROPIC
    schema = ANISOTROPIC.describe()["parameters"]["properties"]
    assert set(schema) == {"strength", "smoothing", "saturation_percentile"}
    assert all(field.get("description") for field in schema.values())


@pytest.mark.parametrize("plugin", [GEODESIC, ANISOTROPIC], ids=lambda p: p.name)
def test_paths_are_edge_connected_with_right_ends(wolf, plugin):
    rng = np.random.default_rng(0)
    params = plugin.parse_params({})
    for start, end in rng.integers(0, wolf.n_vertices, (15, 2)):
        path = plugin.run(wolf, int(start), int(end), params)
        assert path.dtype == np.int64
        assert path[0] == start and path[-1] == end
        check_edge_path(wolf.edge_graph, path)
        assert len(np.unique(path)) == len(path)  # a shortest path never revisits a vertex
    assert plugin.run(wolf, 7, 7, params).tolist() == [7]


@pytest.mark.parametrize(
    ("first_reach", "tries"),
    [(0.75, 3), (0.05, 3), (0.05, 1)],
    ids=["bidirectional", "bidirectional-regrown", "whole-mesh-fallback"],
)
def test_geodesic_length_equals_dijkstra_distance(wolf, first_reach, tries, monkeypatch):
    monkeypatch.setattr(tracers, "FIRST_REACH", first_reach)
    monkeypatch.setattr(tracers, "BOUNDED_TRIES", tries)
    rng = np.random.default_rng(1)
    starts = rng.integers(0, wolf.n_vertices, 10)
    ends = rng.integers(0, wolf.n_vertices, 10)
    dist = dijkstra(wolf.edge_graph, directed=False, indices=starts)
    # near pairs (the first bounded searches meet) and far ones (a grown reach or the whole-mesh search answers)
    near = [int(np.argsort(dist[i])[40]) for i in range(len(starts))]
    for i, start in enumerate(starts):
        for end in (ends[i], near[i]):
            path = GEODESIC.run(wolf, int(start), int(end), GEODESIC_DEFAULTS)
            assert edge_length(wolf, path) == pytest.approx(dist[i, end], rel=1e-12)


def test_feature_direction_is_the_ruling_on_a_cylinder():
    """Normal-cycle convention: the dominant direction is the one of *least* bending, and anisotropy = 1/r."""
    nu, nv, radius = 48, 41, 2.0
    theta, z = np.meshgrid(np.linspace(0, 2 * np.pi, nu, endpoint=False), np.linspace(0, 6, nv), indexing="ij")
    vertices = np.c_[radius * np.cos(theta).ravel(), radius * np.sin(theta).ravel(), z.ravel()]
    mesh = build_mesh(vertices, grid_faces(nu, nv, wrap_u=True))
    directions, anisotropy = tracers.feature_field(mesh, smoothing=1)
    inner = (z.ravel() > 1) & (z.ravel() < 5)  # away from the open ends
    assert np.median(np.abs(directions[inner, 2])) > 0.99
    assert np.median(anisotropy[inner]) == pytest.approx(1 / radius, rel=0.05)


@pytest.mark.parametrize("slope", [1.0, 0.3, -1.0], ids=["ridge", "shallow-ridge", "valley"])
def test_anisotropic_follows_the_crest(slope):
    mesh, off_crest, ny = roof(slope)
    row = ny // 2 - 4  # both endpoints 4 rows (about 0.8) down the same slope, 12 apart along the crest
    start, end = row, (mesh.n_vertices // ny - 1) * ny + row
    geodesic = GEODESIC.run(mesh, start, end, GEODESIC_DEFAULTS)
    anisotropic = ANISOTROPIC.run(mesh, start, end, ANISOTROPIC_DEFAULTS)
    check_edge_path(mesh.edge_graph, anisotropic)
    # the straight path stays down the slope; the anisotropic one climbs to the crest and runs along it
    assert off_crest[geodesic].mean() > 0.6
    assert off_crest[anisotropic].mean() < 0.25 * off_crest[geodesic].mean()
    assert np.mean(off_crest[anisotropic] < 1e-9) > 0.6
    directions, _ = tracers.feature_field(mesh, smoothing=2)
    assert np.median(np.abs(directions[off_crest < 1e-9, 0])) > 0.99  # the crest direction is x


def test_wrong_direction_would_not_follow_the_crest(monkeypatch):
    """The crest test has teeth: the same metric rotated by 90 degrees leaves the path down the slope."""
    mesh, off_crest, ny = roof(1.0)
    real = tracers.feature_field

    def rotated(mesh, smoothing=2):
        directions, anisotropy = real(mesh, smoothing)
        across = np.cross(directions, [0.0, 0.0, 1.0])  # horizontal and perpendicular to the feature
        across /= np.maximum(np.linalg.norm(across, axis=1, keepdims=True), 1e-12)
        return across, anisotropy

    monkeypatch.setattr(tracers, "feature_field", rotated)
    row = ny // 2 - 4
    path = ANISOTROPIC.run(mesh, row, (mesh.n_vertices // ny - 1) * ny + row, ANISOTROPIC_DEFAULTS)
    assert off_crest[path].mean() > 0.5


def test_anisotropic_weights_bounds_and_zero_strength(wolf):
    params = ANISOTROPIC.parse_params({"strength": 3.0})
    weights = tracers.anisotropic_weights(wolf, params)
    length = wolf.edge_lengths
    assert np.all(weights <= length * (1 + 1e-12))
    assert np.all(weights >= length / 4.0 * (1 - 1e-12))
    assert np.any(weights < 0.3 * length)  # some edges lie along saturated features
    flat = tracers.anisotropic_weights(wolf, ANISOTROPIC.parse_params({"strength": 0.0}))
    np.testing.assert_array_equal(flat, length)


@pytest.mark.parametrize("factor", [1000.0, 1e-3])
def test_anisotropic_path_is_scale_invariant(factor):
    mesh, _, ny = roof(1.0, seed=3)
    bumpy = mesh.vertices.copy()
    bumpy[:, 2] += 0.15 * np.sin(1.3 * bumpy[:, 0]) * np.cos(2.1 * bumpy[:, 1])  # features of several sizes
    mesh = build_mesh(bumpy, mesh.faces)
    scaled = build_mesh(bumpy * factor + np.array([5.0, -2.0, 1.0]) * factor, mesh.faces)
    rng = np.random.default_rng(4)
    for start, end in rng.integers(0, mesh.n_vertices, (8, 2)):
        a = ANISOTROPIC.run(mesh, int(start), int(end), ANISOTROPIC_DEFAULTS)
        b = ANISOTROPIC.run(scaled, int(start), int(end), ANISOTROPIC_DEFAULTS)
        np.testing.assert_array_equal(a, b)


def test_graph_is_cached_on_the_mesh_per_params():
    mesh, _, _ = roof(1.0, nx=6, ny=5)
    g1 = tracers.anisotropic_graph(mesh, ANISOTROPIC_DEFAULTS)
    assert tracers.anisotropic_graph(mesh, ANISOTROPIC_DEFAULTS) is g1
    assert len(mesh.derived) == 2  # the feature field and the graph
    assert tracers.anisotropic_graph(mesh, ANISOTROPIC.parse_params({"strength": 2.0})) is not g1
    assert len(mesh.derived) == 3  # the same feature field serves both graphs


def test_cache_is_bounded():
    mesh, _, _ = roof(1.0, nx=6, ny=5)
    for strength in range(mesh.derived.maxsize + 4):
        ANISOTROPIC.run(mesh, 0, mesh.n_vertices - 1, ANISOTROPIC.parse_params({"strength": strength}))
    assert len(mesh.derived) == mesh.derived.maxsize


# ----------------------------------------------------------------------------------------------------------
# Bad input


@pytest.mark.parametrize("plugin", [GEODESIC, ANISOTROPIC], ids=lambda p: p.name)
def test_unknown_params_field_is_rejected(plugin):
    mesh, _, _ = roof(1.0, nx=6, ny=5)
    with pytest.raises(CurvefmError, match=f"bad parameters for '{plugin.name}'.*colour"):
        plugin.parse_params({"colour": "red"})
    with pytest.raises(CurvefmError, match="colour"):
        trace_curve(mesh, waypoints=[0, 3], tracer=plugin.name, params={"colour": "red"})


def test_bad_parameter_values_are_rejected():
    with pytest.raises(CurvefmError, match="strength"):
        ANISOTROPIC.parse_params({"strength": -1})
    with pytest.raises(CurvefmError, match="saturation_percentile"):
        ANISOTROPIC.parse_params({"saturation_percentile": 0})


@pytest.mark.parametrize("plugin", [GEODESIC, ANISOTROPIC], ids=lambda p: p.name)
def test_endpoints_on_different_components(plugin):
    a, _, _ = roof(1.0, nx=6, ny=5, seed=1)
    vertices = np.r_[a.vertices, a.vertices + [0.0, 0.0, 10.0]]
    faces = np.r_[a.faces, a.faces + a.n_vertices]
    mesh = build_mesh(vertices, faces, name="two-pieces")
    assert mesh.report.components == 2
    with pytest.raises(CurvefmError, match="different connected components"):
        plugin.run(mesh, 0, a.n_vertices + 3, plugin.parse_params({}))
    # within one component it works
    assert plugin.run(mesh, a.n_vertices, a.n_vertices + 3, plugin.parse_params({}))[-1] == a.n_vertices + 3


@pytest.mark.parametrize("plugin", [GEODESIC, ANISOTROPIC], ids=lambda p: p.name)
@pytest.mark.parametrize("bad", [-1, 30, 2.5, "3"])
def test_bad_endpoints(plugin, bad):
    mesh, _, _ = roof(1.0, nx=6, ny=5)
    with pytest.raises(CurvefmError, match="start vertex"):
        plugin.run(mesh, bad, 0, plugin.parse_params({}))
    with pytest.raises(CurvefmError, match="end vertex"):
        plugin.run(mesh, 0, bad, plugin.parse_params({}))


# ----------------------------------------------------------------------------------------------------------
# tracing near a display copy (big meshes)


@pytest.fixture(scope="module")
def fine_faust(shared_data):
    """FAUST tr_reg_000 subdivided once (27,554 vertices) and its display copy of about 3,000."""
    faust = load_mesh(shared_data / "faust" / "tr_reg_000.off")
    mesh = build_mesh(*trimesh.remesh.subdivide(faust.vertices, faust.faces), name="faust-subdivided")
    return mesh, display_mesh(mesh, 3000)


def seeded_pairs(mesh, count: int, seed: int) -> list[tuple[int, int]]:
    return [(int(a), int(b)) for a, b in np.random.default_rng(seed).integers(0, mesh.n_vertices, (count, 2))]


def test_a_guided_geodesic_is_a_path_of_the_mesh_in_its_corridor_and_as_short_as_the_whole_search(fine_faust):
    mesh, guide = fine_faust
    for start, end in seeded_pairs(mesh, 12, 2):
        path = tracers.trace_geodesic_guided(mesh, start, end, GEODESIC_DEFAULTS, guide)
        assert path.dtype == np.int64 and path[0] == start and path[-1] == end
        check_edge_path(mesh.edge_graph, path)
        band = tracers.corridor(mesh, guide, start, end)
        assert len(band) < 0.4 * mesh.n_vertices and np.isin(path, band).all()
        shortest = edge_length(mesh, GEODESIC.run(mesh, start, end, GEODESIC_DEFAULTS))
        assert shortest <= edge_length(mesh, path) <= 1.01 * shortest


def test_trace_curve_traces_near_the_guide_it_is_given(fine_faust):
    mesh, guide = fine_faust
    waypoints = [int(mesh.file_ids[v]) for v in (10, 20_000, 5_000)]
    guided = trace_curve(mesh, waypoints=waypoints, guide=guide)
    pieces = [
        tracers.trace_geodesic_guided(mesh, a, b, GEODESIC_DEFAULTS, guide) for a, b in ((10, 20_000), (20_000, 5_000))
    ]
    np.testing.assert_array_equal(guided, np.r_[pieces[0], pieces[1][1:]])
    # a tracer without run_guided traces on the whole mesh, guide or not
    np.testing.assert_array_equal(
        trace_curve(mesh, waypoints=waypoints, tracer="anisotropic", guide=guide),
        trace_curve(mesh, waypoints=waypoints, tracer="anisotropic"),
    )


def test_a_corridor_that_falls_apart_leaves_the_search_to_the_whole_mesh(fine_faust):
    mesh, guide = fine_faust
    start, end = seeded_pairs(mesh, 1, 3)[0]
    to_start = dijkstra(mesh.edge_graph, directed=True, indices=start)
    # the vertices half way between the ends, given to a display vertex far from both: a band no path avoids
    middle = np.abs(to_start - 0.5 * to_start[end]) < 0.05 * to_start[end]
    far = guide.nearest[int(np.argmax(np.minimum(to_start, dijkstra(mesh.edge_graph, directed=True, indices=end))))]
    cut = DisplayMesh(guide.vertex_ids, guide.faces, np.where(middle, far, guide.nearest), guide.n_vertices)
    band = tracers.corridor(mesh, cut, start, end)
    assert not np.isin(far, cut.nearest[band]).any()  # the far display vertex is outside the corridor
    first, last = np.searchsorted(band, [start, end])
    inside = dijkstra(mesh.edge_graph[band][:, band], directed=True, indices=int(first))
    assert not np.isfinite(inside[last])  # the corridor does not join the ends
    path = tracers.trace_geodesic_guided(mesh, start, end, GEODESIC_DEFAULTS, cut)
    assert edge_length(mesh, path) == pytest.approx(to_start[end], rel=1e-12)
