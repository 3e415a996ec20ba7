"""Slow clients against a real server: connections that trickle their headers are closed, a body that stops
arriving answers 408 with the published error body, and a client that goes away mid-body is no internal error."""

from __future__ import annotations

import json
import socket
import time

import pytest

HEADER_TIMEOUT_S, BODY_TIMEOUT_S = 1.0, 1.0
TRICKLERS = 50


@pytest.fixture(scope="module")
def server(module_processes, tmp_path_factory):
    env = {"CURVEFM_HEADER_TIMEOUT": str(HEADER_TIMEOUT_S), "CURVEFM_BODY_TIMEOUT": str(BODY_TIMEOUT_S)}
    return module_processes.api(tmp_path_factory.mktemp("slow") / "data", env=env)


def connect(server) -> socket.socket:
    host, port = server.url.removeprefix("http://").split(":")
    connection = socket.create_connection((host, int(port)), timeout=30)
    return connection


def read_response(connection: socket.socket) -> tuple[bytes, bytes]:
    """One HTTP response: (status line, body), the body read to its Content-Length."""
    data = b""
    while b"\r\n\r\n" not in data:
        data += connection.recv(65536)
    head, _, body = data.partition(b"\r\n\r\n")
    length = int(
        next(line.split(b":")[1] for line in head.split(b"\r\n") if line.lower().startswith(b"content-length"))
    )
    while len(body) < length:
        body += connection.recv(65536)
    return head.split(b"\r\n")[0], body


def closed_by_server(connection: socket.socket) -> bool:
    """Whether the server closed the connection (reads end) rather than keeping it open (the read times out)."""
    try:
        while connection.recv(4096):
            pass
        return True
    except (TimeoutError, ConnectionResetError) as error:
        return isinstance(error, ConnectionResetError)


def test_connections_that_trickle_their_headers_are_closed(server):
    connections = [connect(server) for _ in range(TRICKLERS)]
    for connection in connections:
        connection.sendall(b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ")  # and never more
    time.sleep(3 * HEADER_TIMEOUT_S)
    for connection in connections:
        connection.settimeout(3 * HEADER_TIMEOUT_S)
        assert closed_by_server(connection)
        connection.close()
    assert server.client.get("/health").status_code == 200


def test_a_kept_alive_connection_is_not_cut_while_it_answers_requests(server):
    connection = connect(server)
    for _ in range(3):
        connection.sendall(b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        assert read_response(connection)[0].startswith(b"HTTP/1.1 200")
        time.sleep(HEADER_TIMEOUT_S / 2)
    connection.close()


def test_a_body_that_stops_arriving_answers_408_naming_the_setting(server):
    connection = connect(server)
    head = (
        f"POST /sessions HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer {server.token}\r\n"
        "Content-Type: application/json\r\nContent-Length: 1000\r\n\r\n"
    )
    connection.sendall(head.encode() + b'{"source": "')  # then nothing
    status, body = read_response(connection)
    assert status.startswith(b"HTTP/1.1 408"), status
    body = json.loads(body)
    assert body["error"] and "CURVEFM_BODY_TIMEOUT" in body["detail"], body
    connection.close()
    assert server.client.get("/sessions").json() == []  # nothing stored


@pytest.mark.parametrize(
    ("path", "content_type", "start"),
    [
        (
            "/shapes",
            "multipart/form-data; boundary=b",
            b'--b\r\nContent-Disposition: form-data; name="file"; filename="a.off"',
        ),
        ("/sessions", "application/json", b'{"source": "'),
    ],
)
def test_a_client_that_goes_away_mid_body_is_not_an_internal_error(server, path, content_type, start):
    connection = connect(server)
    head = (
        f"POST {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer {server.token}\r\n"
        f"Content-Type: {content_type}\r\nContent-Length: 100000\r\n\r\n"
    )
    connection.sendall(head.encode() + start)
    time.sleep(0.3)
    connection.close()
    time.sleep(0.5)
    assert server.client.get("/health").status_code == 200
    log = server.log.read_text()
    assert "internal error" not in log.lower() and "Traceback" not in log, log[-3000:]
