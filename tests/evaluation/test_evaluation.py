"""Geodesic error evaluation and ground-truth readers.

Synthetic shapes (a flat square, a sphere) give analytic distances; the real benchmark files in the shared
data folder check the readers' index bases. Tests that need that folder skip when it is absent (fail under CI).
"""

from __future__ import annotations

import json
from functools import cache

import numpy as np
import pytest
from scipy.spatial import ConvexHull, Delaunay
from support.ci import unavailable

from curvefm.errors import CurvefmError
from curvefm.evaluation import (
    evaluate_map,
    faust5k_truth,
    ground_truth_for,
    read_lion2cat,
    read_pid,
    read_vts,
    shared_data_dir,
)
from curvefm.geometry import (
    build_mesh,
    farthest_point_sampling,
    geodesic_diameter,
    geodesic_distances,
    load_mesh,
    pair_geodesic_distances,
)

# ------------------------------------------------------------------------------------------------------
# Synthetic shapes


def grid_square(n: int = 41):
    """Unit square, regular n x n grid, each cell split along the same diagonal. Vertex id = iy * n + ix."""
    x = np.linspace(0.0, 1.0, n)
    gx, gy = np.meshgrid(x, x)
    vertices = np.c_[gx.ravel(), gy.ravel(), np.zeros(n * n)]
    ids = np.arange(n * n).reshape(n, n)
    a, b, c, d = ids[:-1, :-1].ravel(), ids[:-1, 1:].ravel(), ids[1:, 1:].ravel(), ids[1:, :-1].ravel()
    faces = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    return build_mesh(vertices, faces, name="grid")


def jittered_square(n: int = 50, seed: int = 0):
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, n)
    p = np.stack(np.meshgrid(x, x), -1).reshape(-1, 2)
    inner = (p > 0).all(1) & (p < 1).all(1)
    h = 1.0 / (n - 1)
    p[inner] += rng.uniform(-0.3 * h, 0.3 * h, size=(int(inner.sum()), 2))
    return build_mesh(np.c_[p, np.zeros(len(p))], Delaunay(p).simplices, name="jittered")


def fibonacci_sphere(n: int = 3000):
    i = np.arange(n) + 0.5
    phi, theta = np.arccos(1 - 2 * i / n), np.pi * (1 + 5**0.5) * i
    p = np.c_[np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)]
    return build_mesh(p, ConvexHull(p).simplices, name="sphere")


def relative_bias(mesh, truth_of, source, diagonals):
    d = geodesic_distances(mesh, [source], diagonals=diagonals)[0]
    truth = truth_of(mesh.vertices, mesh.vertices[source])
    far = truth > 0.2 * truth.max()
    return d[far] / truth[far] - 1.0


def plane_distance(v, s):
    return np.linalg.norm(v - s, axis=1)


def sphere_distance(v, s):
    return np.arccos(np.clip(v @ s, -1.0, 1.0))


# ------------------------------------------------------------------------------------------------------
# Distances


def test_plane_distances_close_to_euclidean_and_diagonals_help():
    mesh = jittered_square()
    center = int(np.argmin(np.linalg.norm(mesh.vertices[:, :2] - 0.5, axis=1)))
    with_diagonals = relative_bias(mesh, plane_distance, center, True)
    edges_only = relative_bias(mesh, plane_distance, center, False)
    assert with_diagonals.min() > -1e-9  # graph paths lie on the surface: never shorter than the geodesic
    assert with_diagonals.mean() < 0.03 and with_diagonals.max() < 0.08
    assert edges_only.mean() > 2 * with_diagonals.mean()


def test_sphere_distances_and_diameter():
    mesh = fibonacci_sphere()
    bias = relative_bias(mesh, sphere_distance, 0, True)
    assert abs(bias.mean()) < 0.03 and np.abs(bias).max() < 0.06
    assert relative_bias(mesh, sphere_distance, 0, False).mean() > 0.04
    assert geodesic_diameter(mesh) == pytest.approx(np.pi, rel=0.04)


def test_pair_distances_match_full_rows():
    mesh = fibonacci_sphere(1500)
    rng = np.random.default_rng(1)
    a = rng.integers(0, mesh.n_vertices, 400)
    b = np.r_[rng.integers(0, mesh.n_vertices, 200), mesh.faces[a[200:], 1]]  # far and adjacent pairs
    b[:5] = a[:5]  # zero-distance pairs
    full = geodesic_distances(mesh, np.arange(mesh.n_vertices))
    # a tiny chunk forces many chunks and the growing-radius retries
    pairs = pair_geodesic_distances(mesh, a, b, chunk_bytes=20 * 8 * mesh.n_vertices)
    np.testing.assert_allclose(pairs, full[a, b], rtol=1e-12)
    assert np.all(pairs[:5] == 0)


def test_identity_and_shifted_maps_on_a_grid():
    n, k = 41, 3
    mesh = grid_square(n)
    ix = np.arange(n * n) % n
    keep = np.flatnonzero(ix < n - k)
    truth = (keep, keep)
    identity = evaluate_map(np.arange(n * n), truth, mesh)
    assert identity.mean == 0 and identity.max == 0 and identity.auc == pytest.approx(1.0)
    assert identity.count == keep.size and np.all(identity.curve == 1.0)

    shifted = np.arange(n * n)
    shifted[keep] += k  # k grid steps along +x: the geodesic error is exactly k * h
    summary = evaluate_map(shifted, np.c_[keep, keep], mesh)
    error = k / (n - 1)
    assert summary.diameter >= np.sqrt(2) - 1e-12
    assert summary.mean * summary.diameter == pytest.approx(error, rel=1e-12)
    assert summary.median * summary.diameter == pytest.approx(error, rel=1e-12)
    assert summary.mean_area == pytest.approx(error, rel=1e-9)  # area is 1
    below = summary.radii < error / summary.diameter - 1e-9
    assert np.all(summary.curve[below] == 0) and np.all(summary.curve[~below] == 1)
    data = json.loads(json.dumps(summary.as_dict()))
    assert len(data["radii"]) == len(data["curve"]) == 51 and data["count"] == keep.size


def test_bad_inputs_raise_clear_errors():
    mesh = grid_square(5)
    with pytest.raises(CurvefmError, match="out of range"):
        evaluate_map(np.full(25, 99), (np.arange(25), np.arange(25)), mesh)
    with pytest.raises(CurvefmError, match="differ in length"):
        evaluate_map(np.arange(25), (np.arange(25), np.arange(3)), mesh)
    with pytest.raises(CurvefmError, match="empty"):
        evaluate_map(np.arange(25), (np.arange(0), np.arange(0)), mesh)
    with pytest.raises(CurvefmError, match="count"):
        farthest_point_sampling(mesh, 26)


def test_farthest_point_sampling_picks_corners_first():
    n = 21
    mesh = grid_square(n)
    corners = {0, n - 1, n * (n - 1), n * n - 1}
    samples = farthest_point_sampling(mesh, 30, seed_vertex=0)
    assert samples[0] == 0 and samples[1] == n * n - 1
    assert set(samples[:4].tolist()) == corners
    assert len(set(samples.tolist())) == 30
    d = geodesic_distances(mesh, samples)[:, samples]
    assert d[~np.eye(30, dtype=bool)].min() > 0.1  # well spread: no two samples close together


# ------------------------------------------------------------------------------------------------------
# Real data


@pytest.fixture(scope="module")
def data():
    try:
        return shared_data_dir()
    except CurvefmError as exc:
        reason = exc.message
    unavailable(reason)


@cache
def mesh_at(path):
    return load_mesh(path)


def test_shared_data_dir_missing_is_a_clear_error(monkeypatch, tmp_path):
    monkeypatch.setenv("CURVEFM_SHARED_DATA", str(tmp_path / "nowhere"))
    with pytest.raises(CurvefmError, match="CURVEFM_SHARED_DATA"):
        shared_data_dir()


def test_faust_identity_is_zero_and_random_is_large(data):
    px, py = data / "faust" / "tr_reg_000.off", data / "faust" / "tr_reg_011.off"
    x, y = mesh_at(px), mesh_at(py)
    truth = ground_truth_for(px, py, x, y)
    assert truth.kind == "identity" and len(truth) == 6890
    perfect = evaluate_map(np.arange(x.n_vertices), truth, y)
    assert perfect.mean == 0 and perfect.count == 6890
    rng = np.random.default_rng(0)
    rows = rng.choice(len(truth), 300, replace=False)  # a subset keeps the random map cheap
    random = evaluate_map(rng.integers(0, y.n_vertices, x.n_vertices), (truth.ids_X[rows], truth.ids_Y[rows]), y)
    assert random.mean > 0.2 and random.curve[-1] < 0.6 and random.mean_area > 0.2


def test_faust_5k_vts_are_one_based(data):
    five, full = data / "faust_5k_bcicp" / "tr_reg_000.off", data / "faust" / "tr_reg_000.off"
    mesh_5k, mesh_full = mesh_at(five), mesh_at(full)
    raw = np.loadtxt(data / "faust_5k_bcicp" / "corres" / "tr_reg_000.vts", dtype=np.int64)
    assert np.array_equal(read_vts(data / "faust_5k_bcicp" / "corres" / "tr_reg_000.vts"), raw - 1)
    truth = ground_truth_for(five, full, mesh_5k, mesh_full)
    assert truth.kind == "faust5k-sampleid" and len(truth) == 5000
    # the same body, remeshed, translated and scaled: a similarity fit of the pairs must be close
    a = mesh_5k.vertices[truth.ids_X] - mesh_5k.vertices[truth.ids_X].mean(0)
    b = mesh_full.vertices[truth.ids_Y] - mesh_full.vertices[truth.ids_Y].mean(0)
    u, s, vt = np.linalg.svd(a.T @ b)
    fitted = s.sum() / (a**2).sum() * a @ (u @ vt)
    assert np.linalg.norm(fitted - b) / np.linalg.norm(b) < 0.05

    other = data / "faust_5k_bcicp" / "tr_reg_001.off"
    pair = ground_truth_for(five, other, mesh_5k, mesh_at(other))
    assert pair.kind == "faust5k-vts" and len(pair) == 5000
    assert pair.ids_X.max() < mesh_5k.n_vertices and pair.ids_Y.max() < mesh_at(other).n_vertices
    swapped = faust5k_truth(five, other, mesh_5k, mesh_at(other), symmetric=True)
    assert not np.array_equal(swapped.ids_Y, pair.ids_Y)
    back = ground_truth_for(full, five, mesh_full, mesh_5k)  # the other direction swaps the columns
    assert np.array_equal(back.ids_X, truth.ids_Y) and np.array_equal(back.ids_Y, truth.ids_X)


def test_tosca_landmarks(data):
    counts = {"cat": 21, "dog": 21, "horse": 21, "wolf": 21, "centaur": 46}
    counts |= {"david": 36, "michael": 36, "victoria": 36, "gorilla": 36}
    for cls, count in counts.items():
        ids = read_pid(data / "tosca" / "Corrs" / f"{cls}.pid")
        assert ids.size == count and ids.min() >= 0
        with open(data / "tosca" / f"{'gorilla1' if cls == 'gorilla' else cls + '0'}.off") as f:
            header = f.readline().split()
            n_vertices = int(header[1]) if len(header) > 1 else int(f.readline().split()[0])
        assert ids.max() < n_vertices
    wolf0, wolf1, horse = (data / "tosca" / f"{name}.off" for name in ("wolf0", "wolf1", "horse0"))
    within = ground_truth_for(wolf0, wolf1, mesh_at(wolf0), mesh_at(wolf1))
    assert within.kind == "identity" and len(within) == 4344
    sparse = ground_truth_for(wolf0, wolf1, mesh_at(wolf0), mesh_at(wolf1), dense=False)
    assert sparse.kind == "tosca-landmarks" and len(sparse) == 21
    across = ground_truth_for(wolf0, horse, mesh_at(wolf0), mesh_at(horse))
    assert across.kind == "tosca-landmarks" and len(across) == 21 and not across.dense
    p2p = np.zeros(mesh_at(wolf0).n_vertices, dtype=np.int64)
    p2p[across.ids_X] = across.ids_Y
    assert evaluate_map(p2p, across, mesh_at(horse)).mean == 0
    with pytest.raises(CurvefmError, match="no landmark ground truth"):
        ground_truth_for(wolf0, data / "tosca" / "centaur0.off")  # refused before loading


def test_cat_lion_ground_truth(data):
    folder = data / "nonisometric" / "pyfm_cat_lion"
    cat_path, lion_path = folder / "cat-00.off", folder / "lion-00.off"
    cat, lion = mesh_at(cat_path), mesh_at(lion_path)
    lion2cat = read_lion2cat(folder / "lion2cat")
    assert lion2cat.size == lion.n_vertices == 5000
    assert lion2cat.min() >= 0 and lion2cat.max() < cat.n_vertices
    dense = ground_truth_for(lion_path, cat_path, lion, cat)
    assert dense.kind == "lion2cat" and np.array_equal(dense.ids_X, np.arange(5000))
    landmarks = ground_truth_for(lion_path, cat_path, lion, cat, dense=False)
    assert len(landmarks) == 20
    # the dense map agrees with the hand-picked landmarks (index bases consistent)
    agreement = evaluate_map(lion2cat, landmarks, cat)
    assert agreement.mean < 0.02
    reverse = ground_truth_for(cat_path, lion_path, cat, lion, dense=False)
    assert np.array_equal(reverse.ids_X, landmarks.ids_Y) and np.array_equal(reverse.ids_Y, landmarks.ids_X)


def test_unknown_pair_is_refused(data):
    spot = data / "textured" / "spot" / "spot_triangulated.obj"
    with pytest.raises(CurvefmError, match="no known ground truth"):
        ground_truth_for(spot, data / "faust" / "tr_reg_000.off")
    with pytest.raises(CurvefmError, match="not found"):
        ground_truth_for(data / "faust" / "nope.off", data / "faust" / "tr_reg_000.off")
