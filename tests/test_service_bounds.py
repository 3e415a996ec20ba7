"""Bounded work per request, over HTTP against a real server: integers beyond int64, the configured limits (each
named in its 413), and request bodies counted as they arrive, chunked or with a Content-Length that lies."""

from __future__ import annotations

import socket
import time
import uuid
from pathlib import Path

import numpy as np
import pytest
from shapes import ellipsoid
from test_service_errors import expect, snapshot

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
    body = expect(server.client.post(url, json=explicit), 413, "too_large")
    assert_names_limit(body, "max_path_vertices", "vertices in the target path")
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


def test_k_is_limited_for_bases_sessions_and_converters(server, session):
    k = LIMITS["max_k"] + 1
    body = expect(server.client.post(f"/shapes/{server.shapes[0]}/bases", json={"k": k}), 413, "too_large")
    assert_names_limit(body, "max_k", f"k = {k}")
    new = {"source": server.shapes[0], "target": server.shapes[1], "k": k}
    assert_names_limit(expect(server.client.post("/sessions", json=new), 413, "too_large"), "max_k", f"k = {k}")
    server.client.post(f"/sessions/{session}/curves", json={"source": [0, 50], "target": [0, 50]}).raise_for_status()
    refine = {"converter": "zoomout", "params": {"k_init": 20, "k_final": k}}
    body = expect(server.client.post(f"/sessions/{session}/refine", json=refine), 413, "too_large")
    assert_names_limit(body, "max_k", f"a basis of {k} functions")


def test_a_json_body_over_its_limit_is_a_413_declared_or_chunked(server, session):
    url = f"/sessions/{session}/curves"
    payload = b'{"source": [0, 1], "target": [' + b"1, " * LIMITS["max_body_bytes"] + b'1], "explicit": true}'
    headers = {"Content-Type": "application/json"}
    body = expect(server.client.post(url, content=payload, headers=headers), 413, "too_large")
    assert_names_limit(body, "max_body_bytes", f"a request body of {len(payload)} bytes")
    body = expect(server.client.post(url, content=chunks(payload), headers=headers), 413, "too_large")
    assert_names_limit(body, "max_body_bytes", "the request body")
    assert curves_of(server, session) == []


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
    body = expect(api.client.post(f"/shapes/{shape}/bases", json={"k": 6}), 413, "too_large", "--max-k")
    assert "the limit of 5 (max_k" in body["detail"], body
    assert api.client.post(f"/shapes/{shape}/bases", json={"k": 5}).status_code == 202
