"""curvefm.client against a real API process: the README's notebook example, typed errors with the server's
messages, jobs (progress, state, cancel), and the token from CURVEFM_TOKEN."""

from __future__ import annotations

import numpy as np
import pytest

from curvefm.client import Client, Curve, JobFailed
from curvefm.errors import Conflict, InvalidInput, NotFound, Unauthenticated
from curvefm.geometry import save_mesh
from curvefm.service.demo import demo_shapes

K = 20
CURVES = [([10, 2000], [10, 2000]), ([500, 3500], [500, 3500]), ([100, 4000], [100, 4000])]
"""Waypoints on the demo shapes, which share their vertex ids."""


@pytest.fixture(scope="module")
def api(module_processes, tmp_path_factory):
    return module_processes.api(tmp_path_factory.mktemp("client") / "data")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("shapes")
    paths = []
    for mesh in demo_shapes():
        save_mesh(mesh, folder / f"{mesh.name}.off")
        paths.append(folder / f"{mesh.name}.off")
    return paths


@pytest.fixture(scope="module")
def client(api):
    with Client(api.url, token=api.token) as client:
        yield client


@pytest.fixture(scope="module")
def shape_ids(client, files):
    ids = [client.upload(path) for path in files]
    for shape_id in ids:
        client.basis(shape_id, k=K).wait(progress=False)
    return ids


def test_the_notebook_example(client, api, shape_ids, files, capsys):
    src, tgt = shape_ids
    assert client.upload(files[0]) == src  # the content hash: the same mesh, the same id
    s = client.session(src, tgt, k=K)
    added = [s.add_curve(source=source, target=target) for source, target in CURVES]
    assert [c.id for c in s.curves] == [c.id for c in added] and isinstance(added[0], Curve)
    assert added[0].path_source[0] == CURVES[0][0][0] and added[0].path_source[-1] == CURVES[0][0][1]

    C = s.map()
    served = api.client.get(f"/sessions/{s.id}/map").json()
    assert C.shape == (K, K) and np.array_equal(C, np.array(served["C_source_to_target"]))
    assert np.array_equal(s.map("target_to_source"), np.array(served["C_target_to_source"]))

    job = s.refine("nearest-neighbor")
    r = job.wait()
    assert "refine" in capsys.readouterr().err  # the progress bar
    assert job.state == "finished" and r.revision == s.refresh()["revision"]
    for name, array in (("map_target_to_source.txt", r.map_target_to_source),
                        ("map_source_to_target.txt", r.map_source_to_target)):
        text = api.client.get(f"/jobs/{r.job_id}/files/{name}").raise_for_status().text
        assert np.array_equal(array, np.loadtxt(text.splitlines(), dtype=int)), name
    assert len(r.map_target_to_source) == len(demo_shapes()[1].file_ids)
    assert set(r.files) >= {"map_target_to_source.txt", "target_textured.obj"}


def test_removing_a_curve_changes_the_map(client, shape_ids):
    s = client.session(*shape_ids, k=K)
    first, second = (s.add_curve(source=a, target=b) for a, b in CURVES[:2])
    with_both = s.map()
    s.remove_curve(second)
    assert [c.id for c in s.curves] == [first.id]
    assert not np.allclose(s.map(), with_both)


def test_error_answers_raise_the_projects_exceptions_with_the_servers_message(client, shape_ids):
    s = client.session(*shape_ids, k=K)
    with pytest.raises(Conflict, match="out of range") as error:
        s.add_curve(source=[0, 10**6], target=[0, 1])
    assert error.value.status == 409 and error.value.body["error"] == "conflict"
    with pytest.raises(NotFound, match="no-such-session"):
        client.open_session("no-such-session")
    with pytest.raises(InvalidInput) as error:
        client.session(*shape_ids, k=0)
    assert error.value.status == 422 and error.value.body["fields"]
    with pytest.raises(Conflict, match="no curves"):
        s.refine()


def test_the_token_comes_from_curvefm_token(api, monkeypatch):
    monkeypatch.setenv("CURVEFM_TOKEN", api.token)
    with Client(api.url) as client:
        assert isinstance(client.sessions(), list)
    monkeypatch.delenv("CURVEFM_TOKEN")
    with Client(api.url) as client, pytest.raises(Unauthenticated, match="needs credentials") as error:
        client.sessions()
    assert error.value.status == 401


def test_a_canceled_job_ends_canceled_and_waiting_on_it_raises(client, shape_ids):
    s = client.session(*shape_ids, k=K)
    s.add_curve(source=CURVES[0][0], target=CURVES[0][1])
    job = s.refine("rhm").cancel()  # a running job stops at its next progress report
    with pytest.raises(JobFailed, match="canceled") as error:
        job.wait(timeout=60, progress=False)
    assert error.value.info["id"] == job.id and job.state == "canceled"
    assert job.cancel().info["state"] == "canceled"  # canceling again changes nothing
