"""Mesh loading, saving, validation and identity."""

import numpy as np
import pytest
import trimesh

from curvefm.errors import CurvefmError, ResourceLimit
from curvefm.geometry import build_mesh, load_mesh, save_mesh


def grid(n=6, shuffle_seed=0):
    """A bumpy grid whose vertex order is shuffled, so it differs from the order of first use in faces."""
    xs, ys = np.meshgrid(np.arange(n), np.arange(n))
    vertices = np.c_[xs.ravel(), ys.ravel(), 0.3 * np.sin(xs.ravel()) + 0.1 * ys.ravel() ** 2].astype(float)
    faces = []
    for i in range(n - 1):
        for j in range(n - 1):
            a = i * n + j
            faces += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    perm = np.random.default_rng(shuffle_seed).permutation(len(vertices))
    return vertices[perm], np.argsort(perm)[np.array(faces)]


@pytest.mark.parametrize("suffix", [".ply", ".off", ".obj"])
def test_vertex_ids_survive_save_and_load(tmp_path, suffix):
    mesh = build_mesh(*grid(), name="grid")
    save_mesh(mesh, tmp_path / f"m{suffix}")
    loaded = load_mesh(tmp_path / f"m{suffix}")
    np.testing.assert_allclose(loaded.vertices, mesh.vertices, rtol=0, atol=1e-7)
    np.testing.assert_array_equal(loaded.faces, mesh.faces)


def test_glb_keeps_buffer_vertex_order(tmp_path):
    vertices, faces = grid()
    trimesh.Trimesh(vertices, faces, process=False).export(tmp_path / "m.glb")
    loaded = load_mesh(tmp_path / "m.glb")
    np.testing.assert_allclose(loaded.vertices, vertices, atol=1e-6)
    np.testing.assert_array_equal(loaded.faces, faces)


def test_stl_numbers_vertices_by_first_appearance(tmp_path):
    vertices, faces = grid()
    first_use = np.unique(faces.ravel(), return_index=True)
    order = first_use[0][np.argsort(first_use[1])]
    rank = np.argsort(order)
    mesh = build_mesh(vertices[order], rank[faces])  # already in first-use order: STL keeps these ids
    save_mesh(mesh, tmp_path / "m.stl")
    loaded = load_mesh(tmp_path / "m.stl")
    np.testing.assert_allclose(loaded.vertices, mesh.vertices, atol=1e-5)
    np.testing.assert_array_equal(loaded.faces, mesh.faces)


def test_obj_keeps_file_order_and_texture_coordinates(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 3/3 4/4 1/1\nf 3/3 1/1 2/2\n"
    (tmp_path / "q.obj").write_text(text)
    mesh = load_mesh(tmp_path / "q.obj")
    np.testing.assert_array_equal(mesh.vertices[:, :2], [[0, 0], [1, 0], [1, 1], [0, 1]])
    np.testing.assert_array_equal(mesh.uv, [[0, 0], [1, 0], [1, 1], [0, 1]])


def test_real_obj_ids_match_the_file(shared_data):
    path = shared_data / "textured" / "ogre" / "bs_rest.obj"
    first = next(line for line in path.open() if line.startswith("v "))
    mesh = load_mesh(path)
    assert mesh.n_vertices == 19985
    np.testing.assert_allclose(mesh.vertices[0], [float(x) for x in first.split()[1:4]])
    assert mesh.uv is not None and mesh.uv.shape == (19985, 2)


def test_content_hash_is_stable_and_discriminates():
    a = build_mesh(*grid())
    b = build_mesh(*grid())
    vertices, faces = grid()
    vertices[0, 0] += 1e-9
    assert a.content_hash == b.content_hash
    assert build_mesh(vertices, faces).content_hash != a.content_hash


def test_polygons_are_triangulated_and_reported():
    mesh = build_mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2, 3]])
    assert len(mesh.faces) == 2
    assert mesh.report.triangulated_polygons == 1


def test_unreferenced_vertices_are_dropped_but_file_ids_stay_valid():
    vertices = [[5, 5, 5], [0, 0, 0], [1, 0, 0], [0, 1, 0], [9, 9, 9]]
    mesh = build_mesh(vertices, [[1, 2, 3]])
    assert mesh.n_vertices == 3 and mesh.n_file_vertices == 5
    assert mesh.report.unreferenced_vertices_removed == 2
    np.testing.assert_array_equal(mesh.internal_ids([1, 2, 3]), [0, 1, 2])
    with pytest.raises(CurvefmError, match="belongs to no face"):
        mesh.internal_ids([4])


def test_degenerate_faces_are_removed_and_reported():
    vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]]
    mesh = build_mesh(vertices, [[0, 1, 2], [0, 1, 3], [1, 1, 2]])  # second is flat, third repeats a corner
    assert len(mesh.faces) == 1
    assert mesh.report.degenerate_faces_removed == 2


def test_non_manifold_edges_and_components_are_reported_not_fatal():
    vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [5, 5, 5], [6, 5, 5], [5, 6, 5]]
    faces = [[0, 1, 2], [1, 0, 3], [0, 1, 4], [5, 6, 7]]
    mesh = build_mesh(vertices, faces)
    assert mesh.report.non_manifold_edges == 1
    assert mesh.report.components == 2
    assert any("components" in w for w in mesh.report.warnings)


@pytest.mark.parametrize(
    "vertices, faces, message",
    [
        (np.zeros((0, 3)), [[0, 1, 2]], "empty"),
        ([[0, 0, 0], [1, 0, np.nan], [0, 1, 0]], [[0, 1, 2]], "non-finite"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 7]], "refers to vertex 7"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1]], "face 0 has 2 corners"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [], "no faces"),
        ([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]], "degenerate"),
        ([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]], r"\(n, 3\)"),
    ],
)
def test_bad_meshes_are_rejected_with_a_clear_message(vertices, faces, message):
    with pytest.raises(CurvefmError, match=message):
        build_mesh(vertices, faces)


def test_huge_meshes_are_rejected(monkeypatch):
    monkeypatch.setenv("CURVEFM_MAX_VERTICES", "10")
    with pytest.raises(ResourceLimit, match="more than the limit of 10"):
        build_mesh(*grid())


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("bad.off", "this is not a mesh\n", "not an OFF file"),
        ("cut.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n", "fewer vertex ids than it declares"),
        ("short.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n", "file is shorter"),
        ("empty.ply", "", "could not read any vertices"),
        ("broken.obj", "v 0 0 zero\n", "not a valid OBJ"),
        ("mesh.xyz", "1 2 3\n", "unsupported mesh format"),
    ],
)
def test_bad_files_are_rejected_with_a_clear_message(tmp_path, name, content, message):
    (tmp_path / name).write_text(content)
    with pytest.raises(CurvefmError, match=message):
        load_mesh(tmp_path / name)


def test_out_of_range_user_ids_name_the_problem():
    mesh = build_mesh(*grid())
    with pytest.raises(CurvefmError, match="out of range.*36 vertices"):
        mesh.internal_ids([3, 36])
