"""A records' database that stops answering while the API runs (a server restarting, a host name that stops
resolving, connections refused): every request that needs it answers 503 with ``Retry-After`` in the published
error schema, never 500, whichever part of the request meets the outage (the credentials of a write are checked by
a middleware before the route runs); the API answers again once the database does, and the Python client's
retries ride out a short outage. The outage is real: the test's own PostgreSQL database refuses connections
(``ALLOW_CONNECTIONS false``) and its open ones are ended."""

from __future__ import annotations

import threading

import pytest
import trimesh
from support.records import Databases

from curvefm.client import Client
from curvefm.errors import Unavailable


@pytest.fixture
def outage_api(processes, tmp_path, monkeypatch):
    """An API process on a PostgreSQL database of its own, and a switch that stops and restarts that database
    answering."""
    databases = Databases.connect()
    data = tmp_path / "data"
    url = databases.url(data)
    name = url.rsplit("/", 1)[1]
    monkeypatch.setenv("CURVEFM_DATABASE_URL", url)  # the test's own users_of() (the token) reads it too
    api = processes.api(data, env={"CURVEFM_DATABASE_URL": url})

    def answering(yes: bool) -> None:
        databases.admin.execute(f'ALTER DATABASE "{name}" ALLOW_CONNECTIONS {str(yes).lower()}')
        if not yes:
            databases.admin.execute("SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE datname = %s", [name])

    try:
        yield api, answering
    finally:
        answering(True)
        processes.stop_all()
        databases.drop_all()


def expect_503(response) -> None:
    assert response.status_code == 503, response.text
    body = response.json()
    assert set(body) == {"error", "detail"} and body["error"] == "unavailable", body
    assert "records' database" in body["detail"] and "/" not in body["detail"].split("(", 1)[0], body
    assert int(response.headers["Retry-After"]) > 0


def test_a_database_that_stops_answering_is_503_everywhere_then_the_api_recovers(outage_api, tmp_path):
    api, answering = outage_api
    mesh = tmp_path / "ball.off"
    trimesh.creation.icosphere(2).export(mesh)
    shape = api.upload(mesh)
    answering(False)
    expect_503(api.client.post("/sessions", json={"source": shape, "target": shape, "k": 20}))  # credentials first
    expect_503(api.client.get("/sessions"))  # the route's own dependency
    expect_503(api.client.get(f"/shapes/{shape}"))
    health = api.client.get("/health")
    assert health.status_code == 503 and str(api.data_dir) not in health.text, health.text
    answering(True)
    assert api.client.get("/health").status_code == 200
    assert api.client.get(f"/shapes/{shape}").status_code == 200
    assert "internal error" not in api.log.read_text()


def test_the_client_retries_a_503_until_the_database_answers_again(outage_api):
    api, answering = outage_api
    answering(False)
    with Client(api.url, token=api.token, retries=0) as impatient, pytest.raises(Unavailable):
        impatient.shapes()
    back = threading.Timer(1.0, answering, args=(True,))
    back.start()
    try:
        with Client(api.url, token=api.token) as client:
            assert client.shapes() == []  # refused while the database was away, answered after the retry
    finally:
        back.join()
