"""Display copies of big meshes (curvefm.geometry.display) on a real scan: FAUST tr_reg_000, 6,890 vertices."""

import numpy as np
import pytest

from curvefm.geometry import closest_point_weights, display_mesh, load_mesh
from curvefm.records.sessions import sessions_of
from curvefm.session import LiveSessions
from curvefm.store import Store

TARGET = 3000


@pytest.fixture(scope="module")
def faust(shared_data):
    return load_mesh(shared_data / "faust" / "tr_reg_000.off")


@pytest.fixture(scope="module")
def copy(faust):
    return display_mesh(faust, TARGET)


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6)


def test_display_vertices_are_distinct_vertices_of_the_mesh(faust, copy):
    ids = copy.vertex_ids
    assert 0.9 * TARGET <= len(ids) <= 1.05 * TARGET
    assert np.all(np.diff(ids) > 0) and ids[0] >= 0 and ids[-1] < faust.n_vertices
    assert copy.n_vertices == faust.n_vertices


def test_faces_are_proper_and_every_display_vertex_is_used(copy):
    faces = copy.faces
    assert faces.min() == 0 and faces.max() == len(copy.vertex_ids) - 1
    assert len(np.unique(faces)) == len(copy.vertex_ids)
    assert np.all((faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2]))
    assert len(np.unique(np.sort(faces, axis=1), axis=0)) == len(faces)


def test_a_closed_consistently_wound_mesh_gives_a_closed_consistently_wound_copy(faust, copy):
    """What lets the UI draw the copy from its outer side only: each edge has two faces, run once each way."""
    for faces in (faust.faces, copy.faces):
        directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
        assert len(np.unique(directed, axis=0)) == len(directed)
        assert np.all(np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)[1] == 2)


def test_the_copy_follows_the_surface_and_keeps_its_winding(faust, copy):
    vertices = faust.vertices[copy.vertex_ids]
    on_copy = closest_point_weights(faust.vertices, vertices, copy.faces) @ vertices
    diagonal = np.linalg.norm(np.ptp(faust.vertices, axis=0))
    assert np.linalg.norm(on_copy - faust.vertices, axis=1).max() < 0.01 * diagonal
    whole, coarse = signed_volume(faust.vertices, faust.faces), signed_volume(vertices, copy.faces)
    assert np.sign(whole) == np.sign(coarse) and abs(coarse - whole) < 0.03 * abs(whole)


def test_nearest_names_the_closest_display_vertex(faust, copy):
    np.testing.assert_array_equal(copy.nearest[copy.vertex_ids], np.arange(len(copy.vertex_ids)))
    sample = np.random.default_rng(0).choice(faust.n_vertices, 200, replace=False)
    points = faust.vertices[copy.vertex_ids]
    distances = np.linalg.norm(faust.vertices[sample, None] - points[None], axis=2)
    np.testing.assert_allclose(distances[np.arange(200), copy.nearest[sample]], distances.min(axis=1))


def test_rows_of_and_region_of(faust, copy):
    chosen = copy.vertex_ids[[5, 17]]
    not_shown = np.setdiff1d(np.arange(faust.n_vertices), copy.vertex_ids)[0]
    np.testing.assert_array_equal(copy.rows_of(np.array([chosen[0], not_shown, chosen[1]])), [5, -1, 17])
    region = copy.region_of(chosen)
    assert region[chosen].all() and region.sum() > 2
    np.testing.assert_array_equal(region, np.isin(copy.nearest, [5, 17]))


def test_cover_is_the_mesh_vertices_nearest_to_the_rows(faust, copy):
    rows = np.array([0, 9, 17, len(copy.vertex_ids) - 1])
    np.testing.assert_array_equal(copy.cover(rows), np.flatnonzero(np.isin(copy.nearest, rows)))
    assert len(copy.cover(np.arange(len(copy.vertex_ids)))) == faust.n_vertices
    assert len(copy.cover(np.array([], dtype=np.int64))) == 0


def test_the_copy_is_the_same_every_time(faust, copy):
    again = display_mesh(faust, TARGET)
    np.testing.assert_array_equal(again.vertex_ids, copy.vertex_ids)
    np.testing.assert_array_equal(again.faces, copy.faces)


def test_live_sessions_make_a_display_copy_once_and_only_for_big_meshes(tmp_path, faust):
    store = Store(tmp_path)
    store.put_mesh(faust)
    shape = faust.content_hash
    live = LiveSessions(store, sessions_of(store), display_vertices=TARGET)
    first = live.display(shape)
    assert first is live.display(shape) and len(first.vertex_ids) < faust.n_vertices
    for threshold in (0, faust.n_vertices):  # 0: never; a mesh of the threshold's size is drawn whole
        assert LiveSessions(store, sessions_of(store), display_vertices=threshold).display(shape) is None


def test_curves_are_traced_near_a_stored_display_copy_on_meshes_of_the_threshold_and_above(tmp_path, faust):
    store = Store(tmp_path)
    shape = store.put_mesh(faust)
    live = LiveSessions(store, sessions_of(store), display_vertices=TARGET, guided_trace_vertices=faust.n_vertices)
    assert live.guide(shape) is None  # none made yet: an edit does not wait for one
    made = store.ensure_display(faust, TARGET)
    np.testing.assert_array_equal(live.guide(shape).vertex_ids, made.vertex_ids)
    above = LiveSessions(store, sessions_of(store), display_vertices=TARGET, guided_trace_vertices=faust.n_vertices + 1)
    assert above.guide(shape) is None


def test_display_copies_are_kept_in_the_store_for_other_processes(tmp_path, faust):
    store = Store(tmp_path)
    shape = store.put_mesh(faust)
    made = LiveSessions(store, sessions_of(store), display_vertices=TARGET).display(shape)
    path = store.display_path(shape, TARGET)
    assert path.is_file()
    read = LiveSessions(store, sessions_of(store), display_vertices=TARGET).display(shape)  # another process
    for name in ("vertex_ids", "faces", "nearest"):
        np.testing.assert_array_equal(getattr(read, name), getattr(made, name))
    path.write_bytes(b"not an npz")  # a damaged copy is made again, and replaced
    again = LiveSessions(store, sessions_of(store), display_vertices=TARGET).display(shape)
    np.testing.assert_array_equal(again.vertex_ids, made.vertex_ids)
    assert store.get_display(shape, TARGET) is not None
    store.delete_mesh(shape)
    assert not path.exists()
