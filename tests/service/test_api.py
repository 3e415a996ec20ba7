"""The API's everyday paths over HTTP: documentation, plugins, shapes, curve edits, maps and transfers."""

from __future__ import annotations

import gzip
import http.client
import json
import struct
import time

import numpy as np
import pytest

from curvefm.fmap.round_trip import CLEAR_OF_CURVES
from curvefm.geometry import texture_coordinates
from curvefm.service.demo import demo_shapes
from curvefm.session import MAX_VERTEX_ID

K = 30


@pytest.fixture(scope="module")
def server(module_processes, tmp_path_factory):
    folder = tmp_path_factory.mktemp("api")
    api = module_processes.api(folder / "data")
    api.shapes, api.session = api.demo_pair(folder, K)
    return api


def test_documentation_and_plugins(server):
    assert server.client.get("/docs").status_code == 200
    paths = server.client.get("/openapi.json").json()["paths"]
    assert {"/shapes", "/sessions/{session_id}/curves", "/jobs/{job_id}", "/plugins"} <= set(paths)
    plugins = server.client.get("/plugins").json()
    assert {p["name"] for p in plugins["tracer"]} >= {"geodesic", "anisotropic"}
    assert "properties" in plugins["tracer"][0]["parameters"]
    assert "<html" in server.client.get("/").text.lower()  # the web UI


def vertex_id_fields(schema) -> list[dict]:
    """Every integer schema bounded as a file vertex id, and every list of them, in ``schema``."""
    found = []
    if isinstance(schema, dict):
        bound = schema.get("maximum") == MAX_VERTEX_ID or schema.get("items", {}).get("maximum") == MAX_VERTEX_ID
        found += [schema] if bound else []
        schema = list(schema.values())
    if isinstance(schema, list):
        found += [field for value in schema for field in vertex_id_fields(value)]
    return found


def test_the_schema_gives_vertex_ids_that_exist_as_examples(server):
    """Swagger UI fills example requests from the examples, else from the bound: 2147483647, on no mesh."""
    fields = vertex_id_fields(server.client.get("/openapi.json").json()["components"]["schemas"])
    assert len(fields) >= 8  # the curve specs' sides, a member's answer, a template's waypoints, points asked for
    for field in fields:
        examples = field["examples"]
        flat = [v for example in examples for v in (example if isinstance(example, list) else [example])]
        assert flat and max(flat) < 4098, field  # ids of the demo shapes
        if field.get("type") == "array":
            assert all(len(example) >= field.get("minItems", 1) for example in examples), field


def test_shapes_are_listed_and_their_mesh_decodes(server):
    listed = {shape["id"]: shape for shape in server.client.get("/shapes").json()}
    assert set(server.shapes) <= set(listed)
    source = listed[server.shapes[0]]
    assert (source["n_vertices"], source["bases"][0]["k"]) == (4098, K)

    payload = server.client.get(f"/shapes/{server.shapes[0]}/mesh").raise_for_status().content
    (header_length,) = struct.unpack("<I", payload[:4])
    header = json.loads(payload[4 : 4 + header_length])
    assert header_length % 4 == 0

    def array(name: str) -> np.ndarray:
        layout = header["arrays"][name]
        start = 4 + header_length + layout["offset"]
        return np.frombuffer(payload, layout["dtype"], int(np.prod(layout["shape"])), start).reshape(layout["shape"])

    mesh = demo_shapes()[0]
    assert np.allclose(array("vertices"), mesh.vertices, atol=1e-5)
    assert np.array_equal(array("faces"), mesh.faces)
    assert np.array_equal(array("file_ids"), np.arange(4098))
    assert np.allclose(array("texcoords"), texture_coordinates(mesh), atol=1e-6)  # what the uv transfer carries
    as_json = server.client.get(f"/shapes/{server.shapes[0]}/mesh", params={"format": "json"}).json()
    assert np.array_equal(as_json["faces"], mesh.faces)


def test_the_binary_mesh_is_gzipped_for_clients_that_accept_it(server):
    """The same bytes either way; gzipped on the wire (about half) only when the client says it decodes gzip."""
    url = f"/shapes/{server.shapes[0]}/mesh"
    plain = server.client.get(url, headers={"Accept-Encoding": "identity"}).raise_for_status()
    assert "content-encoding" not in plain.headers
    with server.client.stream("GET", url, headers={"Accept-Encoding": "gzip"}) as zipped:
        assert zipped.headers["content-encoding"] == "gzip" and zipped.headers["vary"] == "Accept-Encoding"
        wire = b"".join(zipped.iter_raw())
    assert len(wire) < 0.8 * len(plain.content)
    assert gzip.decompress(wire) == plain.content


def test_curve_edits_update_the_map_and_the_stored_session(server):
    url = f"/sessions/{server.session}"
    first = server.client.post(f"{url}/curves", json={"source": [19, 432], "target": [19, 432]}).json()
    second = server.client.post(f"{url}/curves", json={"source": [1326, 1332], "target": [1326, 1332]}).json()
    assert second["map"]["n_curves"] == first["map"]["n_curves"] + 1
    C_before = np.array(server.client.get(f"{url}/map").json()["C_source_to_target"])
    assert C_before.shape == (K, K) and np.abs(C_before).sum() > 0

    path = first["curve"]["path_source"]
    replaced = server.client.put(
        f"{url}/curves/{first['curve']['id']}",
        json={"source": path, "target": path, "explicit": True, "weight": 3.0},
    ).json()
    assert replaced["curve"]["tracer"] == "explicit" and replaced["curve"]["path_target"] == path
    C_after = np.array(server.client.get(f"{url}/map").json()["C_source_to_target"])
    assert not np.allclose(C_before, C_after)

    removed = server.client.delete(f"{url}/curves/{second['curve']['id']}").json()
    assert removed["curve"] is None
    stored = server.client.get(url).json()
    assert [c["id"] for c in stored["curves"]] == [first["curve"]["id"]]
    assert stored["revision"] == removed["map"]["revision"]
    summary = next(s for s in server.client.get("/sessions").json() if s["id"] == server.session)
    assert (summary["n_curves"], summary["revision"]) == (1, stored["revision"])


@pytest.mark.parametrize(("function", "columns"), [("uv", 2), ("xyz", 3), ("indicator", 1)])
def test_transfers_are_float32_rows_per_target_vertex(server, function, columns):
    server.client.post(f"/sessions/{server.session}/curves", json={"source": [19, 432], "target": [19, 432]})
    params = {"function": function, "vertices": "19,20,21"}
    response = server.client.get(f"/sessions/{server.session}/transfer", params=params).raise_for_status()
    assert response.headers["X-Shape"] == f"4098,{columns}"
    values = np.frombuffer(response.content, "<f4").reshape(4098, columns)
    assert np.isfinite(values).all() and values.std() > 0


def test_an_idle_connection_stays_open_longer_than_clients_keep_theirs(server):
    """A server that closes idle connections first races the next request on them (a dropped request):
    it must outlast an httpx client's 5 s pool expiry."""
    connection = http.client.HTTPConnection("127.0.0.1", int(server.url.rsplit(":", 1)[1]), timeout=10)
    try:
        connection.request("GET", "/health")
        assert connection.getresponse().read() and connection.sock is not None
        opened = connection.sock
        time.sleep(6)  # longer than uvicorn's default keep-alive (5 s)
        connection.request("GET", "/health")  # closed by the server: RemoteDisconnected
        assert connection.getresponse().status == 200 and connection.sock is opened
    finally:
        connection.close()


def test_quality_is_the_round_trip_drift_per_target_vertex(server):
    server.client.post(f"/sessions/{server.session}/curves", json={"source": [19, 432], "target": [19, 432]})
    revision = server.client.get(f"/sessions/{server.session}").json()["revision"]
    response = server.client.get(f"/sessions/{server.session}/quality").raise_for_status()
    assert response.headers["X-Shape"] == "4098,1" and response.headers["X-Revision"] == str(revision)
    drift = np.frombuffer(response.content, "<f4")
    assert drift.shape == (4098,) and np.isfinite(drift).all() and drift.min() >= 0 and drift.std() > 0
    assert drift.min() <= float(response.headers["X-Score"]) <= drift.max()
    for side in ("Target", "Source"):
        assert 0 <= int(response.headers[f"X-Worst-{side}"]) < 4098
    assert response.headers["X-Prior-Pending"] in ("true", "false")
    # where to click next: the vertex that drifts furthest clear of the curves (the demo meshes keep every file id)
    target = demo_shapes()[1]
    unit = target.vertices / np.sqrt(target.area)
    paths = [curve["path_target"] for curve in server.client.get(f"/sessions/{server.session}").json()["curves"]]
    on_curves = unit[np.concatenate(paths)]
    clear = np.linalg.norm(unit[:, None] - on_curves[None], axis=2).min(axis=1) > CLEAR_OF_CURVES
    assert clear.any() and not clear.all()
    assert drift[int(response.headers["X-Worst-Target"])] == drift[clear].max()


def test_a_suggested_curve_lies_away_from_the_curves_and_adds_as_a_curve(server):
    fresh = server.client.post("/sessions", json={"source": server.shapes[0], "target": server.shapes[1], "k": K})
    first = server.client.get(f"/sessions/{fresh.json()['id']}/suggestion").raise_for_status().json()
    assert len(set(first["source"])) == 2  # with no curve yet: where the drift is largest, far apart
    url = f"/sessions/{server.session}"
    server.client.post(f"{url}/curves", json={"source": [19, 432], "target": [19, 432]}).raise_for_status()
    suggested = server.client.get(f"{url}/suggestion").raise_for_status().json()
    record = server.client.get(url).json()
    assert suggested["revision"] == record["revision"] and isinstance(suggested["prior_pending"], bool)
    source = demo_shapes()[0]
    unit = source.vertices / np.sqrt(source.area)
    on_curves = unit[np.concatenate([curve["path_source"] for curve in record["curves"]])]
    ends = unit[suggested["source"]]
    # the ends lie where no curve is, apart from each other; the demo pair is one shape, so the images land near them
    assert np.linalg.norm(ends[:, None] - on_curves[None], axis=2).min() > CLEAR_OF_CURVES
    assert np.linalg.norm(ends[0] - ends[1]) > CLEAR_OF_CURVES
    assert all(0 <= vertex < 4098 for vertex in suggested["target"])
    spec = {"source": suggested["source"], "target": suggested["target"]}
    added = server.client.post(f"{url}/curves", json=spec).raise_for_status().json()["curve"]
    assert added["path_source"][0] == suggested["source"][0] and added["path_target"][-1] == suggested["target"][1]
    following = server.client.get(f"{url}/suggestion").raise_for_status().json()
    assert following["revision"] > suggested["revision"] and following["source"] != suggested["source"]


def on_edges(mesh, file_ids: list[int]) -> bool:
    """Whether consecutive vertices of a path are joined by an edge of the mesh."""
    path = mesh.internal_ids(file_ids)
    return len(path) > 1 and bool(np.all(mesh.edge_graph[path[:-1], path[1:]] > 0))


def test_the_suggested_curve_is_traced_between_its_ends_and_again_when_an_end_moves(server):
    url = f"/sessions/{server.session}"
    server.client.post(f"{url}/curves", json={"source": [19, 432], "target": [19, 432]}).raise_for_status()
    shapes = dict(zip(("source", "target"), demo_shapes(), strict=True))
    plain = server.client.get(f"{url}/suggestion").raise_for_status().json()
    assert plain["path_source"] is None and plain["path_target"] is None  # traced only when asked
    suggested = server.client.get(f"{url}/suggestion", params={"paths": "true"}).raise_for_status().json()
    for side, mesh in shapes.items():
        path = suggested[f"path_{side}"]
        assert [path[0], path[-1]] == suggested[side] and on_edges(mesh, path)
    moved = {"source": f"{suggested['source'][0]},1000", "target": f"{suggested['target'][0]},1000"}
    again = server.client.get(f"{url}/suggestion", params=moved).raise_for_status().json()
    for side, mesh in shapes.items():
        path = again[f"path_{side}"]
        assert again[side] == [suggested[side][0], 1000] and path[-1] == 1000 and on_edges(mesh, path)
    added = server.client.post(f"{url}/curves", json={"source": again["source"], "target": again["target"]})
    curve = added.raise_for_status().json()["curve"]
    assert curve["path_source"] == again["path_source"] and curve["path_target"] == again["path_target"]
    for params, status in (
        ({"source": "5,5", "target": "1,2"}, 409),  # both ends on one vertex: no curve
        ({"source": "1,2"}, 400),  # the target's ends missing
        ({"source": "1,2,3", "target": "1,2"}, 422),
        ({"source": "1,99999999", "target": "1,2"}, 409),  # no such vertex
    ):
        refused = server.client.get(f"{url}/suggestion", params=params)
        assert refused.status_code == status and "detail" in refused.json()


def test_a_deleted_curve_comes_back_under_its_id_at_its_place(server):
    url = f"/sessions/{server.session}/curves"
    ids = [
        server.client.post(url, json={"source": [19, 432 + i], "target": [19, 432 + i]}).json()["curve"]["id"]
        for i in range(3)
    ]
    before = [c["id"] for c in server.client.get(f"/sessions/{server.session}").json()["curves"]]
    gone = server.client.delete(f"{url}/{ids[1]}").raise_for_status()
    assert gone.json()["map"]["n_curves"] == len(before) - 1
    place = before.index(ids[1])
    spec = {"source": [19, 433], "target": [19, 433]}
    back = server.client.post(url, params={"curve_id": ids[1], "position": place}, json=spec).raise_for_status()
    assert back.json()["curve"]["id"] == ids[1]
    record = server.client.get(f"/sessions/{server.session}").json()
    assert [c["id"] for c in record["curves"]] == before
    for taken in (ids[1], f"c{record['next_curve']}"):  # in use; never handed out
        refused = server.client.post(url, params={"curve_id": taken}, json=spec)
        assert refused.status_code == 409 and taken in refused.json()["detail"]
    assert server.client.post(url, params={"curve_id": "x1"}, json=spec).status_code == 422
    fresh = server.client.post(url, json=spec).raise_for_status().json()["curve"]["id"]
    assert fresh == f"c{record['next_curve']}"  # giving an id back does not move the next one


def test_new_sessions_use_the_combined_energy_unless_they_ask_for_curves(server):
    source, target = server.shapes
    request = {"source": source, "target": target, "k": K}
    created = {
        energy: server.client.post("/sessions", json=request | extra)
        for energy, extra in (("combined", {}), ("curves", {"energy": "curves"}))
    }
    maps = {}
    for energy, response in created.items():
        session = response.raise_for_status().json()
        assert session["energy"] == energy
        url = f"/sessions/{session['id']}"
        server.client.post(f"{url}/curves", json={"source": [19, 432], "target": [19, 432]}).raise_for_status()
        assert server.client.get(url).json()["energy"] == energy
        maps[energy] = np.array(server.client.get(f"{url}/map").json()["C_source_to_target"])
    assert not np.allclose(maps["combined"], maps["curves"], atol=1e-3)
    refused = server.client.post("/sessions", json=request | {"energy": "magic"})
    assert refused.status_code == 422 and "energy" in refused.text


def test_the_landmark_prior_lands_in_the_background_and_then_the_map_stays(server):
    url = f"/sessions/{server.session}"
    server.client.post(f"{url}/curves", json={"source": [100, 3000], "target": [100, 3000]}).raise_for_status()
    first = server.client.get(f"{url}/transfer").raise_for_status()  # solved at once; starts the prior's job
    assert first.headers["X-Prior-Pending"] in ("true", "false")
    latest, deadline = first, time.monotonic() + 60
    while latest.headers["X-Prior-Pending"] == "true":
        assert time.monotonic() < deadline, "the landmark prior did not land within 60 s"
        time.sleep(0.2)
        latest = server.client.get(f"{url}/transfer").raise_for_status()
    assert latest.headers["X-Revision"] == first.headers["X-Revision"]
    if first.headers["X-Prior-Pending"] == "true":  # the prior changed the map of the same revision
        assert first.content != latest.content
    again = server.client.get(f"{url}/transfer").raise_for_status()
    assert again.headers["X-Prior-Pending"] == "false" and again.content == latest.content
