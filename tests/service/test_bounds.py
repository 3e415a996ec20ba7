"""Bounded work per request, over HTTP against a real server: integers beyond int64, the configured limits (each
named in its 413), and request bodies counted as they arrive, chunked or with a Content-Length that lies."""

from __future__ import annotations

import socket
import time
import uuid
from pathlib import Path

import numpy as np
import pytest
from support.errors import expect, snapshot
from support.shapes import ellipsoid

from curvefm.geometry import save_mesh
from curvefm.service.demo import demo_shapes

K = 30
LIMITS = {
    "max_upload_bytes": 2_000_000,
    "max_body_bytes": 100_000,
    "max_waypoints": 8,
    "max_path_vertices": 100,
    "max_curves": 3,
    "max_k": 40,
    "max_json_depth": 32,
    "max_session_bytes": 2500,  # above three traced curves of max_path_vertices (4 x 3 x 204), below two long paths
}
TOO_BIG = 99999999999999999999  # > 2**64


@pytest.fixture(scope="module")
def server(module_processes, tmp_path_factory):
    """An embedded-mode API with small limits and its own temporary folder (TMPDIR), the demo shapes and bases."""
    folder = tmp_path_factory.mktemp("bounds")
    (folder / "tmp").mkdir()
    env = {f"CURVEFM_{name.upper()}": str(value) for name, value in LIMITS.items()} | {"TMPDIR": str(folder / "tmp")}
    api = module_processes.api(folder / "data", env=env)
    api.data, api.tmp = folder / "data", folder / "tmp"
    api.shapes, api.session = api.demo_pair(folder, K)
    return api


@pytest.fixture
def session(server) -> str:
    """A new session of the test's own on the demo pair (the limit on curves counts per session)."""
    body = {"source": server.shapes[0], "target": server.shapes[1], "k": K}
    return server.client.post("/sessions", json=body).raise_for_status().json()["id"]


def curves_of(server, session: str) -> list[dict]:
    return server.client.get(f"/sessions/{session}").raise_for_status().json()["curves"]


def test_integers_beyond_int64_are_a_422_naming_the_field(server, session):
    url = f"/sessions/{session}/curves"
    body = expect(server.client.post(url, json={"source": [1, TOO_BIG], "target": [1, 5]}), 422, "invalid")
    assert body["fields"][0]["field"] == "body.source.1", body
    body = expect(server.client.post(url, json={"source": [1, 5], "target": [-(2**64), 5]}), 422, "invalid")
    assert body["fields"][0]["field"] == "body.target.0", body
    curve = server.client.post(url, json={"source": [0, 5], "target": [0, 5]}).raise_for_status().json()["curve"]
    replace = f"{url}/{curve['id']}"
    body = expect(server.client.put(replace, json={"source": [TOO_BIG, 5], "target": [1, 5]}), 422, "invalid")
    assert body["fields"][0]["field"] == "body.source.0", body
    explicit = {"source": [0, TOO_BIG], "target": [0, 1], "explicit": True}
    expect(server.client.put(replace, json=explicit), 422, "invalid", "body.source.1")
    assert curves_of(server, session) == [curve]


@pytest.mark.parametrize("weight", ["1.7e308", "1e400", "Infinity", "NaN", "0", "-1"])
def test_a_curve_weight_out_of_bounds_is_a_422_and_the_session_stays_usable(server, session, weight):
    url = f"/sessions/{session}/curves"
    text = f'{{"source": [0, 5], "target": [0, 5], "weight": {weight}}}'
    body = expect(server.client.post(url, content=text, headers={"Content-Type": "application/json"}), 422, "invalid")
    assert "weight" in str(body), body
    assert curves_of(server, session) == []
    server.client.post(url, json={"source": [0, 5], "target": [0, 5], "weight": 1e6}).raise_for_status()
    assert server.client.get(f"/sessions/{session}/map").status_code == 200


def test_transfer_vertices_beyond_int64_are_refused_by_the_schema(server, session):
    """The published pattern allows ten digits at most: nothing beyond int64 reaches numpy."""
    transfer = f"/sessions/{session}/transfer"
    for vertices in (f"1,{TOO_BIG}", f"-{TOO_BIG}", "3,-1"):
        response = server.client.get(transfer, params={"function": "indicator", "vertices": vertices})
        body = expect(response, 422, "invalid", "query.vertices")
        assert body["fields"][0]["field"] == "query.vertices", body
    ok = server.client.get(transfer, params={"function": "indicator", "vertices": "1,2"})
    assert ok.status_code == 200 and ok.headers["X-Shape"] == "4098,1"


def test_the_openapi_schema_bounds_vertex_ids(server):
    schemas = server.client.get("/openapi.json").json()["components"]["schemas"]
    for side in ("source", "target"):
        for variant in schemas["CurveSpec"]["anyOf"]:  # one per installed tracer (service/openapi.py)
            items = variant["properties"][side]["items"]
            assert items["type"] == "integer" and (items["minimum"], items["maximum"]) == (0, 2**31 - 1), items
        stored = schemas["CurveRecord"]["properties"][f"path_{side}"]  # int32 arrays in memory, lists in JSON
        assert stored == {"type": "array", "items": {"type": "integer"}, "title": f"Path {side.title()}"}, stored


def test_waypoints_and_path_vertices_are_limited(server, session):
    url = f"/sessions/{session}/curves"
    many = list(range(LIMITS["max_waypoints"] + 1))
    body = expect(server.client.post(url, json={"source": many, "target": [0, 5]}), 413, "too_large")
    assert_names_limit(body, "max_waypoints", f"{len(many)} waypoints on the source")
    explicit = {"source": [0, 1], "target": list(range(LIMITS["max_path_vertices"] + 1)), "explicit": True}
    body = expect(server.client.post(url, json=explicit), 422, "invalid")  # past the schema's maxItems
    assert_names_bound(body, "max_path_vertices", "body.target", f"{LIMITS['max_path_vertices'] + 1} items")
    zigzag = far_apart_waypoints(LIMITS["max_waypoints"])
    body = expect(server.client.post(url, json={"source": zigzag, "target": [0, 5]}), 413, "too_large")
    assert_names_limit(body, "max_path_vertices", "vertices in the traced source path")
    assert curves_of(server, session) == []


def test_curves_per_session_are_limited(server, session):
    url = f"/sessions/{session}/curves"
    for a in range(LIMITS["max_curves"]):
        server.client.post(url, json={"source": [a, a + 40], "target": [a, a + 40]}).raise_for_status()
    body = expect(server.client.post(url, json={"source": [7, 80], "target": [7, 80]}), 413, "too_large")
    assert_names_limit(body, "max_curves", f"{LIMITS['max_curves'] + 1} curves in session {session}")
    assert len(curves_of(server, session)) == LIMITS["max_curves"]
    first = curves_of(server, session)[0]["id"]  # a full session can still be edited
    replaced = server.client.put(f"{url}/{first}", json={"source": [9, 90], "target": [9, 90]})
    assert replaced.status_code == 200, replaced.text


def test_a_session_past_its_size_cap_is_refused_and_keeps_what_it_had(server, session):
    url = f"/sessions/{session}/curves"
    traced = server.client.post(url, json={"source": [0, 50], "target": [0, 50]}).raise_for_status().json()["curve"]
    n = LIMITS["max_path_vertices"]
    long = {"source": back_and_forth(traced["path_source"], n), "target": back_and_forth(traced["path_target"], n)}
    long_curve = {**long, "explicit": True}  # 4 bytes x (2 paths + 2 given) x n = 1600 bytes
    server.client.put(f"{url}/{traced['id']}", json=long_curve).raise_for_status()
    second = server.client.post(url, json={"source": [5, 60], "target": [5, 60]}).raise_for_status().json()["curve"]
    before = server.client.get(f"/sessions/{session}").raise_for_status().json()
    stored = stored_bytes(before["curves"])
    refusals = [  # the answer, and what the session would have stored
        (server.client.post(url, json=long_curve), stored + 16 * n),
        (server.client.put(f"{url}/{second['id']}", json=long_curve), stored - stored_bytes([second]) + 16 * n),
    ]
    for refused, would_store in refusals:
        body = expect(refused, 413, "too_large")
        assert_names_limit(body, "max_session_bytes", f"session {session}'s curves would store {would_store} bytes")
    assert server.client.get(f"/sessions/{session}").json() == before  # nothing stored, the live maps as they were
    assert server.client.get(f"/sessions/{session}/map").json()["revision"] == before["revision"]
    server.client.delete(f"{url}/{second['id']}").raise_for_status()  # a capped session can still be edited


def stored_bytes(curves: list[dict]) -> int:
    """What curves store as ``CURVEFM_MAX_SESSION_BYTES`` counts it: 4 bytes a vertex id, paths and given ids."""
    sides = ("path_source", "path_target")
    return 4 * sum(
        sum(len(c[side]) for side in sides) + len(c["spec"]["source"]) + len(c["spec"]["target"]) for c in curves
    )


def back_and_forth(path: list[int], n: int) -> list[int]:
    """``n`` vertices walking ``path`` forth and back again (each step along an edge of the traced path)."""
    walk = path + path[-2::-1]
    while len(walk) < n:
        walk += walk[1:]
    return walk[:n]


def test_k_is_limited_for_bases_sessions_and_converters(server, session):
    """k past max_k is past the schema's maximum (422 naming the limit); a converter's basis size is the
    converter's to say, so past max_k it is a 413."""
    k = LIMITS["max_k"] + 1
    body = expect(server.client.post(f"/shapes/{server.shapes[0]}/bases", json={"k": k}), 422, "invalid")
    assert_names_bound(body, "max_k", "body.k", f"k = {k}")
    new = {"source": server.shapes[0], "target": server.shapes[1], "k": k}
    assert_names_bound(expect(server.client.post("/sessions", json=new), 422, "invalid"), "max_k", "body.k", f"k = {k}")
    server.client.post(f"/sessions/{session}/curves", json={"source": [0, 50], "target": [0, 50]}).raise_for_status()
    refine = {"converter": "zoomout", "params": {"k_init": 20, "k_final": k}}
    body = expect(server.client.post(f"/sessions/{session}/refine", json=refine), 413, "too_large")
    assert_names_limit(body, "max_k", f"a basis of {k} functions")


def test_the_openapi_schema_states_the_configured_limits(server):
    """The limits known at start are the published bounds (every plugin variant of a request has them), marked
    with their setting; ``max_members`` is the default 200 here, ``max_comment_chars`` 2000."""
    schemas = server.client.get("/openapi.json").json()["components"]["schemas"]
    bounds = {
        ("BasisRequest", "k"): ("maximum", "max_k", LIMITS["max_k"]),
        ("SessionCreate", "k"): ("maximum", "max_k", LIMITS["max_k"]),
        ("CollectionCreate", "k"): ("maximum", "max_k", LIMITS["max_k"]),
        ("CollectionCreate", "curves"): ("maxItems", "max_curves", LIMITS["max_curves"]),
        ("CollectionCreate", "members"): ("maxItems", "max_members", 200),
        ("MembersRequest", "shapes"): ("maxItems", "max_members", 200),
        ("CurveSpec", "source"): ("maxItems", "max_path_vertices", LIMITS["max_path_vertices"]),
        ("TemplateCurveSpec", "waypoints"): ("maxItems", "max_path_vertices", LIMITS["max_path_vertices"]),
        ("AnswerRequest", "target"): ("maxItems", "max_path_vertices", LIMITS["max_path_vertices"]),
        ("NewThread", "text"): ("maxLength", "max_comment_chars", 2000),
        ("CommentReply", "text"): ("maxLength", "max_comment_chars", 2000),
    }
    for (model, field), (keyword, setting, limit) in bounds.items():
        for variant in schemas[model].get("anyOf", [schemas[model]]):
            published = variant["properties"][field]
            assert (published[keyword], published["x-curvefm-limit"]) == (limit, setting), (model, published)
            assert f"CURVEFM_{setting.upper()}" in published["description"], published
    members = schemas["RunRequest"]["anyOf"][0]["properties"]["members"]["anyOf"][0]
    assert (members["maxItems"], members["x-curvefm-limit"]) == (200, "max_members"), members


def test_a_body_past_a_bound_the_schema_states_is_its_422_naming_the_setting(server):
    collection = {"template": server.shapes[0], "curves": [{"waypoints": [0, 5]}] * (LIMITS["max_curves"] + 1)}
    body = expect(server.client.post("/collections", json=collection), 422, "invalid")
    assert_names_bound(body, "max_curves", "body.curves", f"{LIMITS['max_curves'] + 1} items")
    members = {"shapes": ["s"] * 201}
    body = expect(server.client.post("/collections/none/members", json=members), 422, "invalid", "201 items")
    assert body["fields"][0]["field"] == "body.shapes" and body["limit"] == "CURVEFM_MAX_MEMBERS", body
    assert server.client.get("/collections").json() == []


def test_plugin_names_and_parameters_the_schema_refuses_are_a_422(server, session):
    """Every request field naming a plugin takes the installed ones and their parameters as the published schema
    says; anything else is the schema's 422, naming the field (the tracer's, basis's or converter's)."""
    collection = {"template": server.shapes[0]}
    refusals = [
        ("/collections", {**collection, "basis_params": {"bogus": 1}}, "body.basis_params.bogus"),
        ("/collections", {**collection, "basis_plugin": "nope"}, "body.basis_plugin"),
        ("/collections", {**collection, "tracer": "nope"}, "body.tracer"),
        ("/collections", {**collection, "curves": [{"waypoints": [0, 5], "tracer": "nope"}]}, "body.curves.0.tracer"),
        ("/collections/none/runs", {"converter": "nope"}, "body.converter"),
        ("/collections/none/runs", {"converter": "zoomout", "params": {"k_final": "x"}}, "body.params.k_final"),
        (
            "/collections/none/members/m1/curves",
            {"template_curve": "t1", "target": [0, 5], "tracer": "x"},
            "body.tracer",
        ),
        (f"/sessions/{session}/curves", {"source": [0, 5], "target": [0, 5], "tracer": "nope"}, "body.tracer"),
    ]
    for url, request, field in refusals:
        body = expect(server.client.post(url, json=request), 422, "invalid")
        assert body["fields"][0]["field"].startswith(field), (url, request, body)
    assert server.client.get("/collections").json() == []


def test_a_json_body_over_its_limit_is_a_413_declared_or_chunked(server, session):
    url = f"/sessions/{session}/curves"
    payload = b'{"source": [0, 1], "target": [' + b"1, " * LIMITS["max_body_bytes"] + b'1], "explicit": true}'
    headers = {"Content-Type": "application/json"}
    body = expect(server.client.post(url, content=payload, headers=headers), 413, "too_large")
    assert_names_limit(body, "max_body_bytes", f"a request body of {len(payload)} bytes")
    body = expect(server.client.post(url, content=chunks(payload), headers=headers), 413, "too_large")
    assert_names_limit(body, "max_body_bytes", "the request body")
    assert curves_of(server, session) == []


@pytest.mark.parametrize("depth", [40, 1_000, 5_000])
def test_deeply_nested_json_is_a_413_naming_the_limit_on_every_json_route(server, session, depth):
    """Nesting past Python's parser (about 1,000 levels) or past ``max_json_depth`` (32): a 413 naming the limit,
    never a 500, on the curves, in a plugin's parameters and on other JSON routes; nothing is stored."""
    nested = "[" * depth + "]" * depth
    headers = {"Content-Type": "application/json"}
    bodies = [
        (f"/sessions/{session}/curves", f'{{"source": [0, 5], "target": {nested}}}'),
        (f"/sessions/{session}/curves", f'{{"source": [0, 5], "target": [0, 5], "tracer_params": {{"a": {nested}}}}}'),
        ("/sessions", f'{{"source": "{server.shapes[0]}", "target": "{server.shapes[1]}", "k": {nested}}}'),
        (f"/sessions/{session}/refine", f'{{"converter": "zoomout", "params": {{"k_final": {nested}}}}}'),
    ]
    sessions_before = server.client.get("/sessions").json()
    for url, text in bodies:
        body = expect(server.client.post(url, content=text.encode(), headers=headers), 413, "too_large")
        assert_names_limit(body, "max_json_depth", "the JSON body nests arrays and objects")
    assert curves_of(server, session) == []
    assert server.client.get("/sessions").json() == sessions_before


def test_json_nested_within_the_limit_reaches_the_schema_check(server, session):
    text = '{"source": [0, 5], "target": [0, 5], "tracer_params": {"a": [[[[1]]]]}}'
    response = server.client.post(
        f"/sessions/{session}/curves", content=text, headers={"Content-Type": "application/json"}
    )
    assert response.status_code in (201, 422), response.text
    assert "max_json_depth" not in response.text


def test_a_chunked_upload_under_the_limit_is_stored(server, tmp_path):
    mesh = demo_shapes()[0]
    moved = mesh.vertices + np.array([0.0, 0.0, 1e-3])  # another content hash: a new shape
    lines = [f"v {x} {y} {z}" for x, y, z in moved] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh.faces]
    content = ("\n".join(lines) + "\n").encode()
    assert len(content) < LIMITS["max_upload_bytes"]
    body, content_type = multipart("moved.obj", content)
    response = server.client.post("/shapes", content=chunks(body), headers={"Content-Type": content_type})
    assert response.status_code == 201, response.text
    assert response.json()["n_vertices"] == mesh.n_vertices


def test_a_shape_name_is_bounded(server):
    mesh = demo_shapes()[0]
    moved = mesh.vertices + np.array([0.0, 2e-3, 0.0])
    lines = [f"v {x} {y} {z}" for x, y, z in moved] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh.faces]
    content = ("\n".join(lines) + "\n").encode()
    files = {"file": ("x.obj", content)}
    expect(server.client.post("/shapes", files=files, data={"name": "n" * 201}), 422, "invalid", "name")
    long_file = {"file": ("f" * 1_000 + ".obj", content)}
    stored = server.client.post("/shapes", files=long_file).raise_for_status().json()
    assert stored["name"] == "f" * 200
    huge_file = {"file": ("f" * 100_000 + ".obj", content)}  # past the multipart parser's header size
    expect(server.client.post("/shapes", files=huge_file), 400, "invalid")


@pytest.mark.parametrize("how", ["chunked", "lying content-length"])
def test_an_upload_over_the_limit_stops_at_the_limit(server, how):
    """Twice the limit sent, chunked or after a Content-Length of 1 kB: the server answers 413 (chunked) or 422
    (the body it was told of is a form cut short, without the file), writes less than the limit on the way (files,
    answer and log together), and stores nothing."""
    limit = LIMITS["max_upload_bytes"]
    body, content_type = multipart("huge.off", b"OFF\n" + b"0 " * (2 * limit))
    before, written_before = snapshot(server.data), bytes_written(server)
    if how == "chunked":
        response = send_raw(server, chunked_request(body, content_type, server.token))
        assert response.startswith(b"HTTP/1.1 413"), response[:300]
        assert b"max_upload_bytes" in response and b"CURVEFM_MAX_UPLOAD_BYTES" in response, response
    else:
        response = send_raw(server, lying_request(body, content_type, declared=1000, token=server.token))
        assert response.startswith(b"HTTP/1.1 422") and b"body.file" in response, response[:300]
    written = bytes_written(server) - written_before
    assert written < limit, f"the server wrote {written} bytes while refusing a {len(body)}-byte upload"
    assert snapshot(server.data) == before
    assert list(server.tmp.iterdir()) == []
    assert server.client.get("/health").status_code == 200


# -- helpers ----------------------------------------------------------------------------------------------------


def assert_names_limit(body: dict, name: str, what: str) -> None:
    detail = body["detail"]
    assert what in detail and name in detail and f"CURVEFM_{name.upper()}" in detail, detail
    assert str(LIMITS[name]) in detail, detail


def assert_names_bound(body: dict, name: str, field: str, what: str) -> None:
    """A 422 for a bound of the schema that is the configured limit ``name``: the field, and the limit named."""
    assert [problem["field"] for problem in body["fields"]] == [field], body
    assert body["limit"] == f"CURVEFM_{name.upper()}", body
    assert_names_limit(body, name, what)


def far_apart_waypoints(count: int) -> list[int]:
    """Waypoints alternating between two far-apart vertices of the demo source, so the traced path is long."""
    vertices = demo_shapes()[0].vertices
    far = int(np.argmax(np.linalg.norm(vertices - vertices[0], axis=1)))
    return [0, far] * (count // 2)


def chunks(data: bytes, size: int = 16_384):
    """The body as a generator: httpx sends it chunked (no Content-Length)."""
    for start in range(0, len(data), size):
        yield data[start : start + size]


def multipart(filename: str, content: bytes) -> tuple[bytes, str]:
    boundary = uuid.uuid4().hex
    head = (
        f'--{boundary}\r\nContent-Disposition: form-data; name="file"; filename="{filename}"\r\n'
        "Content-Type: application/octet-stream\r\n\r\n"
    ).encode()
    return head + content + f"\r\n--{boundary}--\r\n".encode(), f"multipart/form-data; boundary={boundary}"


def upload_lines(token: str) -> str:
    """The request line and headers of an upload by the test's user (the server answers allowed hosts only)."""
    return f"POST /shapes HTTP/1.1\r\nHost: localhost\r\nAuthorization: Bearer {token}\r\n"


def chunked_request(body: bytes, content_type: str, token: str) -> list[bytes]:
    head = f"{upload_lines(token)}Content-Type: {content_type}\r\nTransfer-Encoding: chunked\r\n\r\n"
    return [head.encode()] + [b"%x\r\n%s\r\n" % (len(part), part) for part in chunks(body)] + [b"0\r\n\r\n"]


def lying_request(body: bytes, content_type: str, declared: int, token: str) -> list[bytes]:
    head = f"{upload_lines(token)}Content-Type: {content_type}\r\nContent-Length: {declared}\r\n\r\n"
    return [head.encode(), *chunks(body)]


def send_raw(server, parts: list[bytes]) -> bytes:
    """Send the request's parts until the server answers or closes the connection; return its answer."""
    host, port = server.url.removeprefix("http://").split(":")
    with socket.create_connection((host, int(port)), timeout=30) as connection:
        answer = b""
        for part in parts:
            try:
                connection.sendall(part)
            except OSError:  # the server answered and closed the connection
                break
            if answer := sent_so_far(connection):
                break
        return answer + read_answer(connection, answer)


def sent_so_far(connection: socket.socket) -> bytes:
    """What the server has answered until now, without waiting."""
    timeout = connection.gettimeout()
    connection.setblocking(False)
    try:
        return connection.recv(65536)
    except BlockingIOError:
        return b""
    finally:
        connection.settimeout(timeout)


def read_answer(connection: socket.socket, start: bytes) -> bytes:
    """The rest of one HTTP answer whose first bytes are ``start`` (headers, then Content-Length bytes)."""
    answer, deadline = start, time.monotonic() + 30
    while time.monotonic() < deadline:
        head, _, body = answer.partition(b"\r\n\r\n")
        lines = head.lower().split(b"\r\n")
        length = [int(line.split(b":")[1]) for line in lines if line.startswith(b"content-length")]
        if length and len(body) >= length[0]:
            break
        chunk = connection.recv(65536)
        if not chunk:
            break
        answer += chunk
    return answer[len(start) :]


def bytes_written(server) -> int:
    """Bytes the server process has passed to write(2) so far: files, sockets and logs alike."""
    for line in Path(f"/proc/{server.process.pid}/io").read_text().splitlines():
        if line.startswith("wchar:"):
            return int(line.split()[1])
    raise AssertionError("no wchar in /proc/PID/io")


def test_a_limit_set_on_the_command_line_wins_over_the_environment(processes, tmp_path):
    save_mesh(ellipsoid(), tmp_path / "ellipsoid.off")
    api = processes.api(tmp_path / "data", env={"CURVEFM_MAX_K": "50"}, args=["--max-k", "5"])
    shape = api.upload(tmp_path / "ellipsoid.off")
    body = expect(api.client.post(f"/shapes/{shape}/bases", json={"k": 6}), 422, "invalid", "--max-k")
    assert "the limit of 5 (max_k" in body["detail"], body
    assert api.client.post(f"/shapes/{shape}/bases", json={"k": 5}).status_code == 202
