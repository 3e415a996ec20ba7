"""Errors over HTTP: each problem is a JSON body naming it, with the status of its error class (4xx for the
user's errors, 500 with an error id for ours); the data directory is unchanged."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from support.errors import expect, snapshot

K = 30
MAX_UPLOAD = 2_000_000
FAILING_TRACERS = {  # tracer name -> what it raises: installed as a third-party package would install them
    "raises-CurvefmError": 'errors.CurvefmError("the tracer refuses these endpoints")',
    "raises-InvalidInput": 'errors.InvalidInput("the tracer refuses these endpoints")',
    "raises-NotFound": 'errors.NotFound("the tracer found no such landmark")',
    "raises-Conflict": 'errors.Conflict("the tracer is busy with this mesh")',
    "raises-ResourceLimit": 'errors.ResourceLimit("the curve is longer than the tracer allows")',
    "raises-InternalError": 'errors.InternalError("the tracer\'s solver did not converge")',
    "raises-KeyError": 'KeyError("a bug in the tracer")',
}


TRACERS_MODULE = """
from pydantic import BaseModel

from curvefm import errors
from curvefm.registry import TracerPlugin


class NoParams(BaseModel):
    pass


def raising(name, make):
    def run(mesh, start, end, params):
        raise make()

    return TracerPlugin(name=name, description="fails on purpose", Params=NoParams, run=run)
"""


def install_failing_tracers(folder: Path) -> Path:
    """A package on its own path entry whose tracers each raise one error (a stand-in for a numerical failure
    or a bug deep in the core, which no well-formed request reaches)."""
    attribute = {name: name.replace("-", "_") for name in FAILING_TRACERS}
    folder.mkdir()
    tracers = [f"{attribute[name]} = raising({name!r}, lambda: {error})" for name, error in FAILING_TRACERS.items()]
    (folder / "failing_tracers.py").write_text(TRACERS_MODULE + "\n".join(tracers) + "\n")
    info = folder / "failing_tracers-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: failing-tracers\nVersion: 0.1\n")
    points = [f"{name} = failing_tracers:{attribute[name]}" for name in FAILING_TRACERS]
    (info / "entry_points.txt").write_text("[curvefm.tracers]\n" + "\n".join(points) + "\n")
    return folder


@pytest.fixture(scope="module")
def server(module_processes, tmp_path_factory):
    """An embedded-mode API with the two demo shapes, their bases, an empty session and the failing tracers."""
    folder = tmp_path_factory.mktemp("errors")
    plugins = str(install_failing_tracers(folder / "plugins"))
    path = os.pathsep.join(filter(None, [plugins, os.environ.get("PYTHONPATH")]))
    # max_k far above the meshes' own bound on k, which test_k_larger_than_the_mesh_allows reaches
    env = {"CURVEFM_MAX_UPLOAD_BYTES": str(MAX_UPLOAD), "CURVEFM_MAX_K": str(10**7), "PYTHONPATH": path}
    api = module_processes.api(folder / "data", env=env)
    api.data = folder / "data"
    api.shapes, api.session = api.demo_pair(folder, K)
    return api


@pytest.fixture(autouse=True)
def store_unchanged(server, request):
    """Rejected requests change nothing; a test that also submits a job (whose record is written, and charged to
    the user's quotas) asks for ``accepted_job`` and may change the job records and the quota ledgers only."""
    ignored = ("curvefm.db/jobs",) if "accepted_job" in request.fixturenames else ()
    before = snapshot(server.data, ignored)
    yield
    assert snapshot(server.data, ignored) == before, "a rejected request changed the data directory"


@pytest.fixture
def accepted_job():
    """See ``store_unchanged``."""


def upload(server, name: str, content: bytes):
    return server.client.post("/shapes", files={"file": (name, content)})


def test_every_error_status_is_documented_as_an_error_body(server):
    documented = {
        (path, method, status): response["content"]["application/json"]["schema"]
        for path, operations in server.client.get("/openapi.json").json()["paths"].items()
        for method, operation in operations.items()
        for status, response in operation["responses"].items()
        if int(status) >= 400
    }
    assert ("/sessions/{session_id}/curves", "post", "422") in documented
    assert ("/health", "get", "500") in documented
    assert {schema["$ref"] for schema in documented.values()} == {"#/components/schemas/ErrorBody"}


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
    expect(server.client.get(path), 404, "not_found")


def test_unknown_ids_in_edits(server):
    expect(server.client.post("/shapes/feedbeef/bases", json={"k": K}), 404, "not_found", "feedbeef")
    curve = {"source": [1, 2], "target": [1, 2]}
    expect(server.client.post("/sessions/nope/curves", json=curve), 404, "not_found", "nope")
    expect(server.client.put(f"/sessions/{server.session}/curves/c99", json=curve), 404, "not_found", "c99")
    expect(server.client.delete(f"/sessions/{server.session}/curves/c99"), 404, "not_found", "c99")
    expect(server.client.delete("/jobs/nope"), 404, "not_found", "nope")
    expect(server.client.put("/plugins"), 405, "invalid", "Method Not Allowed")
    body = {"source": "feedbeef", "target": server.shapes[1], "k": K}
    expect(server.client.post("/sessions", json=body), 404, "not_found", "feedbeef", "source")


def test_vertex_ids_the_shape_does_not_have(server):
    """A vertex id is well formed when it is a non-negative integer (the schema says so: 422 otherwise); one
    the shape does not have conflicts with the stored shape (409)."""
    url = f"/sessions/{server.session}/curves"
    expect(server.client.post(url, json={"source": [0, 99999], "target": [0, 5]}), 409, "conflict", "99999")
    expect(server.client.post(url, json={"source": [0, 5], "target": [-1, 5]}), 422, "invalid", "body.target.0")
    expect(server.client.post(url, json={"source": [0], "target": [0, 5]}), 422, "invalid", "body.source")
    explicit = {"source": [0, 3000], "target": [0, 3000], "explicit": True}
    expect(server.client.post(url, json=explicit), 409, "conflict", "edge-connected")
    expect(server.client.post(url, json={"source": [7, 7], "target": [0, 5]}), 409, "conflict", "same vertex")
    transfer = f"/sessions/{server.session}/transfer"
    indicator = {"function": "indicator", "vertices": "1,99999"}
    expect(server.client.get(transfer, params=indicator), 409, "conflict", "99999")
    expect(server.client.get(transfer, params={**indicator, "vertices": "1,,2"}), 422, "invalid", "vertices")
    assert server.client.get(transfer, params={"function": "curvature"}).status_code == 422


def test_the_indicator_of_no_vertices_is_zero(server):
    response = server.client.get(f"/sessions/{server.session}/transfer", params={"function": "indicator"})
    assert response.status_code == 200, response.text
    rows, columns = map(int, response.headers["X-Shape"].split(","))
    assert len(response.content) == rows * columns * 4 and not response.content.strip(b"\0")


def test_bodies_are_held_to_the_published_schema(server):
    """What pydantic's lax mode would coerce (a string for a number, 0 for a boolean) is refused as the schema
    says."""
    url = f"/sessions/{server.session}/curves"
    for wrong in ({"weight": "2"}, {"explicit": 0}, {"source": [0, "5"]}):
        body = expect(server.client.post(url, json={"source": [0, 5], "target": [0, 5], **wrong}), 422, "invalid")
        assert body["fields"][0]["field"].startswith(f"body.{next(iter(wrong))}"), body


def test_unknown_plugins_list_what_is_installed(server):
    """The schema lists the installed plugins; a request naming another one is refused with that list."""
    session = {"source": server.shapes[0], "target": server.shapes[1], "k": K, "tracer": "laser"}
    expect(server.client.post("/sessions", json=session), 422, "invalid", "body.tracer", "laser", "geodesic")
    curve = {"source": [0, 5], "target": [0, 5], "tracer": "laser"}
    url = f"/sessions/{server.session}/curves"
    expect(server.client.post(url, json=curve), 422, "invalid", "laser", "anisotropic", "geodesic")
    bases = f"/shapes/{server.shapes[0]}/bases"
    expect(server.client.post(bases, json={"k": K, "plugin": "wavelets"}), 422, "invalid", "laplace-beltrami")
    refine = f"/sessions/{server.session}/refine"
    expect(server.client.post(refine, json={"converter": "magic"}), 422, "invalid", "magic", "nearest-neighbor")
    variants = server.client.get("/openapi.json").json()["components"]["schemas"]["RefineRequest"]["anyOf"]
    documented = {variant["properties"]["converter"]["enum"][0] for variant in variants}
    assert {"zoomout", "rhm", "icp", "nearest-neighbor"} <= documented


def test_refine_parameters_are_checked_at_submission(server):
    refine = f"/sessions/{server.session}/refine"
    body = {"converter": "zoomout", "params": {"k_init": 20, "k_final": 10}}
    expect(server.client.post(refine, json=body), 400, "invalid", "zoomout", "k_final")  # what no schema can say
    body = {"converter": "rhm", "params": {"max_iterations": -3}}
    expect(server.client.post(refine, json=body), 422, "invalid", "body.params.max_iterations")


def test_unknown_parameters_are_named(server):
    bases = f"/shapes/{server.shapes[0]}/bases"
    magic = {"k": K, "params": {"laplacian": "magic"}}
    expect(server.client.post(bases, json=magic), 422, "invalid", "body.params.laplacian", "cotangent")
    expect(server.client.post(bases, json={"k": K, "params": {"colour": 1}}), 422, "invalid", "colour")
    curve = {"source": [0, 5], "target": [0, 5], "tracer": "anisotropic", "tracer_params": {"strength": -1}}
    url = f"/sessions/{server.session}/curves"
    expect(server.client.post(url, json=curve), 422, "invalid", "body.tracer_params.strength")
    orphan = {"source": [0, 5], "target": [0, 5], "tracer_params": {"strength": 1}}
    expect(server.client.post(url, json=orphan), 422, "invalid", "tracer_params")
    body = expect(server.client.post(bases, json={"k": K, "colour": 1}), 422, "invalid", "colour")
    assert body["fields"][0]["field"] == "body.colour"
    expect(server.client.post(bases, json={"k": "many"}), 422, "invalid", "body.k")


def test_k_larger_than_the_mesh_allows(server):
    expect(server.client.post(f"/shapes/{server.shapes[0]}/bases", json={"k": 10**6}), 409, "conflict", "too large")
    session = {"source": server.shapes[0], "target": server.shapes[1], "k": 10**6}
    expect(server.client.post("/sessions", json=session), 409, "conflict", "too large")


def test_session_whose_bases_are_not_ready(server):
    session = {"source": server.shapes[0], "target": server.shapes[1], "k": K + 10}
    body = expect(server.client.post("/sessions", json=session), 409, "conflict", server.shapes[0], server.shapes[1])
    assert f"POST /shapes/{server.shapes[0]}/bases" in body["detail"]


def test_refine_needs_curves_and_ended_jobs_cannot_be_canceled(server, accepted_job):
    expect(server.client.post(f"/sessions/{server.session}/refine", json={}), 409, "conflict", "no curves")
    job = server.client.post(f"/shapes/{server.shapes[0]}/bases", json={"k": K}).json()
    assert server.wait_job(job["id"])["state"] == "finished"  # the basis exists: the job ends at once
    expect(server.client.delete(f"/jobs/{job['id']}"), 409, "conflict", "finished")


def add_curve_with(server, tracer: str):
    curve = {"source": [0, 5], "target": [0, 5], "tracer": tracer}
    return server.client.post(f"/sessions/{server.session}/curves", json=curve)


@pytest.mark.parametrize(
    "error, status, kind",
    [
        ("CurvefmError", 400, "invalid"),  # the base class, raised as such by a plugin: the user's error
        ("InvalidInput", 400, "invalid"),
        ("NotFound", 404, "not_found"),
        ("Conflict", 409, "conflict"),
        ("ResourceLimit", 413, "too_large"),
    ],
)
def test_each_user_error_class_has_its_status(server, error, status, kind):
    body = expect(add_curve_with(server, f"raises-{error}"), status, kind, "the tracer")
    assert set(body) == {"error", "detail"}


def test_an_internal_error_is_a_500_with_an_id_and_no_traceback(server):
    response = add_curve_with(server, "raises-InternalError")
    body = expect(response, 500, "internal", "did not converge", "error id")
    assert set(body) == {"error", "detail", "error_id"} and body["error_id"] in body["detail"]
    assert "Traceback" not in response.text and ".py" not in response.text
    logged = server_log_after(server, body["error_id"])
    assert "Traceback" in logged and "InternalError: the tracer's solver did not converge" in logged


def test_an_unexpected_exception_is_an_internal_error_too(server):
    response = add_curve_with(server, "raises-KeyError")
    body = expect(response, 500, "internal", "error id")
    assert "KeyError" not in response.text and "bug" not in response.text  # the log has it, the answer not
    assert "KeyError: 'a bug in the tracer'" in server_log_after(server, body["error_id"])


def server_log_after(server, error_id: str) -> str:
    """The server log from the line that names ``error_id`` on."""
    log = server.log.read_text()
    found = re.search(rf"^.*internal error {error_id}\b", log, flags=re.MULTILINE)
    assert found, f"error id {error_id} is not in the server log:\n{log[-3000:]}"
    return log[found.start() :]
