"""Display copies over HTTP, on a real server process whose threshold is set low (``CURVEFM_DISPLAY_VERTICES=3000``)
so that FAUST's 6,890-vertex scans are drawn coarse: the mesh payload, the display rows of the transfer and the
quality, the points route, and the errors of bad requests."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree
from support.display import THRESHOLD, decode, display_server, mesh
from support.errors import expect as error_body
from support.shapes import ellipsoid, off_bytes


@pytest.fixture(scope="module")
def server(module_processes, tmp_path_factory, shared_data):
    return display_server(module_processes, tmp_path_factory.mktemp("display"), shared_data)


def rows(server, route: str, **params) -> np.ndarray:
    response = server.client.get(f"/sessions/{server.session}/{route}", params=params).raise_for_status()
    n, d = map(int, response.headers["X-Shape"].split(","))
    return np.frombuffer(response.content, "<f4").reshape(n, d)


def test_a_big_shape_is_served_as_a_display_copy_of_its_own_vertices(server):
    header, shown = mesh(server, server.shapes[1])
    full_header, full = mesh(server, server.shapes[1], resolution="full")
    assert header["display_copy"] is True and header["shape_vertices"] == len(full["vertices"]) == 6890
    assert full_header["display_copy"] is False and "vertex_ids" not in full
    ids = shown["vertex_ids"].astype(np.int64)
    assert 0.9 * THRESHOLD <= len(ids) <= 1.05 * THRESHOLD
    assert len(np.unique(ids)) == len(ids) and ids.min() >= 0 and ids.max() < 6890
    np.testing.assert_array_equal(shown["vertices"], full["vertices"][ids])
    np.testing.assert_array_equal(shown["file_ids"], full["file_ids"][ids])
    np.testing.assert_array_equal(shown["texcoords"], full["texcoords"][ids])
    faces = shown["faces"]
    assert faces.max() == len(ids) - 1 and len(faces) < 0.5 * len(full["faces"])
    as_json = server.client.get(f"/shapes/{server.shapes[1]}/mesh", params={"format": "json"}).json()
    assert as_json["display_copy"] is True and as_json["vertex_ids"] == ids.tolist()


def test_a_small_shape_is_served_whole(server):
    small = server.client.post("/shapes", files={"file": ("e.off", off_bytes(ellipsoid(20, 40)))}).json()
    assert small["n_vertices"] < THRESHOLD
    header, arrays = mesh(server, small["id"])
    assert header["display_copy"] is False and header["shape_vertices"] == small["n_vertices"]
    assert "vertex_ids" not in arrays and len(arrays["vertices"]) == small["n_vertices"]
    points = server.client.post(f"/shapes/{small['id']}/points", json={"vertices": [7, 3]}).raise_for_status()
    _, found = decode(points.content)
    np.testing.assert_array_equal(found["nearest_row"], [7, 3])  # drawn whole: each vertex is its own row
    np.testing.assert_array_equal(found["positions"], arrays["vertices"][[7, 3]])


@pytest.mark.parametrize("function", ["uv", "xyz"])
def test_display_transfer_rows_are_the_full_rows_at_the_display_vertices(server, function):
    ids = mesh(server, server.shapes[1])[1]["vertex_ids"]
    full = rows(server, "transfer", function=function)
    shown = rows(server, "transfer", function=function, resolution="display")
    assert full.shape[0] == 6890 and shown.shape == (len(ids), full.shape[1])
    np.testing.assert_allclose(shown, full[ids], rtol=0, atol=2e-5 * np.abs(full).max())


def test_display_quality_rows_are_the_full_rows_at_the_display_vertices(server):
    ids = mesh(server, server.shapes[1])[1]["vertex_ids"]
    url = f"/sessions/{server.session}/quality"
    full = server.client.get(url).raise_for_status()
    shown = server.client.get(url, params={"resolution": "display"}).raise_for_status()
    drift_full, drift_shown = (np.frombuffer(r.content, "<f4") for r in (full, shown))
    np.testing.assert_array_equal(drift_shown, drift_full[ids])
    assert shown.headers["X-Shape"] == f"{len(ids)},1"
    for header in ("X-Score", "X-Worst-Target", "X-Worst-Source"):
        assert shown.headers[header] == full.headers[header]


def test_points_give_positions_and_the_nearest_drawn_row(server):
    source = server.shapes[0]
    _, full = mesh(server, source, resolution="full")
    _, shown = mesh(server, source)
    every = list(range(6890))
    _, found = decode(server.client.post(f"/shapes/{source}/points", json={"vertices": every}).content)
    np.testing.assert_array_equal(found["positions"], full["vertices"])
    distance, nearest = cKDTree(shown["vertices"]).query(full["vertices"])
    chosen = found["nearest_row"].astype(np.int64)
    found_distance = np.linalg.norm(full["vertices"] - shown["vertices"][chosen], axis=1)
    np.testing.assert_allclose(found_distance, distance, rtol=0, atol=1e-6)  # float32 positions
    assert np.mean(chosen == nearest) > 0.99  # ties aside, the same rows
    np.testing.assert_array_equal(chosen[shown["vertex_ids"]], np.arange(len(shown["vertex_ids"])))


def test_a_region_picked_on_the_display_copy_stands_for_the_surface_it_covers(server):
    """An indicator of display vertices (resolution=display) is the indicator of every vertex nearest to them."""
    source = server.shapes[0]
    _, shown = mesh(server, source)
    around = np.linalg.norm(shown["vertices"] - shown["vertices"][100], axis=1)
    chosen = np.flatnonzero(around < 0.1 * np.linalg.norm(np.ptp(shown["vertices"], axis=0)))  # as the UI's region
    picked = ",".join(str(shown["file_ids"][row]) for row in chosen)
    _, found = decode(server.client.post(f"/shapes/{source}/points", json={"vertices": list(range(6890))}).content)
    region = np.flatnonzero(np.isin(found["nearest_row"], chosen))  # FAUST's file ids are its internal ids
    assert len(region) > 1.5 * len(chosen)
    ids = mesh(server, server.shapes[1])[1]["vertex_ids"]
    spread = rows(server, "transfer", function="indicator", vertices=picked, resolution="display")
    explicit = rows(server, "transfer", function="indicator", vertices=",".join(map(str, region)))
    np.testing.assert_allclose(spread, explicit[ids], rtol=0, atol=1e-5)
    alone = rows(server, "transfer", function="indicator", vertices=picked)  # full resolution: the ids alone
    assert explicit.sum() > 1.5 * alone.sum() > 0


def test_bad_requests_answer_the_error_schema(server):
    shape, session = server.shapes[0], f"/sessions/{server.session}"
    for url in (f"/shapes/{shape}/mesh", f"{session}/transfer", f"{session}/quality"):
        body = error_body(server.client.get(url, params={"resolution": "coarse"}), 422, "invalid")
        assert any(problem["field"] == "query.resolution" for problem in body["fields"]), body
    points = f"/shapes/{shape}/points"
    error_body(server.client.post(points, json={"vertices": [0, 6890]}), 409, "conflict", "6890", "out of range")
    error_body(server.client.post(points, json={"vertices": []}), 422, "invalid")
    error_body(server.client.post(points, json={"vertices": [-1]}), 422, "invalid")
    error_body(server.client.post(points, json={"vertices": [1], "extra": 2}), 422, "invalid")
    error_body(server.client.post("/shapes/nope/points", json={"vertices": [1]}), 404, "not_found", "nope")
    error_body(server.client.get("/shapes/nope/mesh"), 404, "not_found", "nope")


def test_the_basis_job_makes_the_display_copy_that_every_api_process_then_reads(processes, tmp_path, shared_data):
    data, env = tmp_path / "data", {"CURVEFM_DISPLAY_VERTICES": str(THRESHOLD)}
    first = processes.api(data, env=env)
    shape = first.upload(shared_data / "faust" / "tr_reg_000.off")
    stored = data / "displays" / shape / f"v{THRESHOLD}.npz"
    assert not stored.exists()  # not made by the upload
    job = first.client.post(f"/shapes/{shape}/bases", json={"k": 10}).raise_for_status().json()
    assert first.wait_job(job["id"])["state"] == "finished"
    assert stored.is_file()  # made by the job, before any page asked for the shape
    made = stored.stat().st_mtime_ns
    with np.load(stored) as arrays:
        ids = arrays["vertex_ids"]
    second = processes.api(data, env=env)  # another API process on the same data
    for api in (second, first):
        header, shown = mesh(api, shape)
        assert header["display_copy"] is True
        np.testing.assert_array_equal(shown["vertex_ids"], ids)
    assert stored.stat().st_mtime_ns == made  # read, never made again
