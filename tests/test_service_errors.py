"""Bad input over HTTP: each problem is a 4xx with a JSON body naming it; the data directory is unchanged."""

from __future__ import annotations

from pathlib import Path

import pytest

K = 30
MAX_UPLOAD = 2_000_000


@pytest.fixture(scope="module")
def server(module_processes, tmp_path_factory):
    """An embedded-mode API with the two demo shapes, their bases and an empty session."""
    folder = tmp_path_factory.mktemp("errors")
    api = module_processes.api(folder / "data", env={"CURVEFM_MAX_UPLOAD_BYTES": str(MAX_UPLOAD)})
    api.data = folder / "data"
    api.shapes, api.session = api.demo_pair(folder, K)
    return api


@pytest.fixture(autouse=True)
def store_unchanged(server):
    before = snapshot(server.data)
    yield
    assert snapshot(server.data) == before, "a rejected request changed the data directory"


def snapshot(folder: Path) -> dict[str, tuple[int, int]]:
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns) for p in folder.rglob("*")}


def expect(response, status: int, kind: str, *words: str) -> dict:
    assert response.status_code == status, response.text
    body = response.json()
    assert body["error"] == kind
    for word in words:
        assert word in body["detail"], body
    return body


def upload(server, name: str, content: bytes):
    return server.client.post("/shapes", files={"file": (name, content)})


def test_malformed_and_unsupported_meshes(server):
    expect(upload(server, "broken.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n"), 400, "invalid", "broken.off")
    expect(upload(server, "junk.ply", b"\x00\x01 not a ply file"), 400, "invalid")
    expect(upload(server, "empty.obj", b""), 400, "invalid", "empty.obj")
    expect(upload(server, "points.obj", b"v 0 0 0\nv 1 0 0\nf 1 2\n"), 400, "invalid", "corners")
    expect(upload(server, "mesh.xyz", b"0 0 0\n"), 400, "invalid", "unsupported", ".off")
    expect(server.client.post("/shapes"), 422, "invalid", "file")


def test_upload_over_the_size_limit(server):
    body = expect(upload(server, "big.off", b"OFF\n" + b"0" * MAX_UPLOAD), 413, "too_large")
    assert "CURVEFM_MAX_UPLOAD_BYTES" in body["detail"]


@pytest.mark.parametrize(
    "path",
    [
        "/shapes/feedbeef",
        "/shapes/feedbeef/mesh",
        "/sessions/nope",
        "/sessions/nope/map",
        "/jobs/nope",
        "/jobs/nope/files/map.txt",
        "/sessions/../../etc/passwd",
    ],
)
def test_unknown_ids(server, path):
    assert server.client.get(path).status_code == 404


def test_unknown_ids_in_edits(server):
    expect(server.client.post("/shapes/feedbeef/bases", json={"k": K}), 404, "not_found", "feedbeef")
    curve = {"source": [1, 2], "target": [1, 2]}
    expect(server.client.post("/sessions/nope/curves", json=curve), 404, "not_found", "nope")
    expect(server.client.put(f"/sessions/{server.session}/curves/c99", json=curve), 404, "not_found", "c99")
    expect(server.client.delete(f"/sessions/{server.session}/curves/c99"), 404, "not_found", "c99")
    expect(server.client.delete("/jobs/nope"), 404, "not_found", "nope")
    body = {"source": "feedbeef", "target": server.shapes[1], "k": K}
    expect(server.client.post("/sessions", json=body), 404, "not_found", "feedbeef", "source")


def test_vertex_ids_out_of_range(server):
    url = f"/sessions/{server.session}/curves"
    expect(server.client.post(url, json={"source": [0, 99999], "target": [0, 5]}), 400, "invalid", "99999")
    expect(server.client.post(url, json={"source": [0, 5], "target": [-1, 5]}), 400, "invalid", "-1")
    explicit = {"source": [0, 3000], "target": [0, 3000], "explicit": True}
    expect(server.client.post(url, json=explicit), 400, "invalid", "edge-connected")
    transfer = f"/sessions/{server.session}/transfer"
    expect(server.client.get(transfer, params={"function": "indicator", "vertices": "1,99999"}), 400, "invalid")
    expect(server.client.get(transfer, params={"function": "indicator"}), 400, "invalid", "vertices")
    assert server.client.get(transfer, params={"function": "curvature"}).status_code == 422


def test_unknown_plugins_list_what_is_installed(server):
    session = {"source": server.shapes[0], "target": server.shapes[1], "k": K, "tracer": "laser"}
    body = expect(server.client.post("/sessions", json=session), 400, "invalid", "laser")
    assert "geodesic" in body["available"]
    curve = {"source": [0, 5], "target": [0, 5], "tracer": "laser"}
    expect(server.client.post(f"/sessions/{server.session}/curves", json=curve), 400, "invalid", "laser")
    body = expect(
        server.client.post(f"/shapes/{server.shapes[0]}/bases", json={"k": K, "plugin": "wavelets"}),
        400,
        "invalid",
        "wavelets",
    )
    assert "laplace-beltrami" in body["available"]
    body = expect(
        server.client.post(f"/sessions/{server.session}/refine", json={"converter": "magic"}),
        400,
        "invalid",
        "magic",
    )
    assert "nearest-neighbor" in body["available"]


def test_refine_parameters_are_checked_at_submission(server):
    refine = f"/sessions/{server.session}/refine"
    body = {"converter": "zoomout", "params": {"k_init": 20, "k_final": 10}}
    expect(server.client.post(refine, json=body), 400, "invalid", "zoomout")
    body = {"converter": "rhm", "params": {"max_iterations": -3}}
    expect(server.client.post(refine, json=body), 400, "invalid", "rhm")


def test_unknown_parameters_are_named(server):
    bases = f"/shapes/{server.shapes[0]}/bases"
    expect(
        server.client.post(bases, json={"k": K, "params": {"laplacian": "magic"}}),
        400,
        "invalid",
        "laplacian",
    )
    expect(server.client.post(bases, json={"k": K, "params": {"colour": 1}}), 400, "invalid", "colour")
    curve = {"source": [0, 5], "target": [0, 5], "tracer": "anisotropic", "tracer_params": {"strength": -1}}
    expect(server.client.post(f"/sessions/{server.session}/curves", json=curve), 400, "invalid", "strength")
    body = expect(server.client.post(bases, json={"k": K, "colour": 1}), 422, "invalid", "colour")
    assert body["fields"][0]["field"] == "body.colour"
    expect(server.client.post(bases, json={"k": "many"}), 422, "invalid", "body.k")


def test_k_larger_than_the_mesh_allows(server):
    expect(
        server.client.post(f"/shapes/{server.shapes[0]}/bases", json={"k": 10**6}),
        400,
        "invalid",
        "too large",
    )
    session = {"source": server.shapes[0], "target": server.shapes[1], "k": 10**6}
    expect(server.client.post("/sessions", json=session), 400, "invalid", "too large")


def test_session_whose_bases_are_not_ready(server):
    session = {"source": server.shapes[0], "target": server.shapes[1], "k": K + 10}
    body = expect(server.client.post("/sessions", json=session), 409, "conflict", server.shapes[0], server.shapes[1])
    assert f"POST /shapes/{server.shapes[0]}/bases" in body["detail"]


def test_refine_needs_curves_and_ended_jobs_cannot_be_canceled(server):
    expect(server.client.post(f"/sessions/{server.session}/refine", json={}), 409, "conflict", "no curves")
    job = server.client.post(f"/shapes/{server.shapes[0]}/bases", json={"k": K}).json()
    assert server.wait_job(job["id"])["state"] == "finished"  # the basis exists: the job ends at once
    expect(server.client.delete(f"/jobs/{job['id']}"), 409, "conflict", "finished")
