"""Integrity by the records' database, over HTTP against real server processes (on SQLite, and on PostgreSQL with
CURVEFM_TEST_DATABASE=postgresql): stable user ids, refused requests that store nothing, a shape in use that
cannot go, two API processes editing one session, the database reported and checked at start, and the old
JSON-file layout imported at the first start."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import httpx
import pytest
from support.errors import expect
from support.lab import CURVE, Lab
from support.legacy_layout import write_legacy
from support.processes import bearer
from support.shapes import ellipsoid, off_bytes

from curvefm.access import users_of


@pytest.fixture(scope="module")
def lab(module_processes, tmp_path_factory) -> Lab:
    return Lab(module_processes.api(tmp_path_factory.mktemp("integrity") / "data"))


@pytest.fixture(scope="module")
def limited(module_processes, tmp_path_factory) -> Lab:
    """A lab whose users may own 2 sessions and store 60,000 bytes."""
    env = {"CURVEFM_QUOTA_SESSIONS": "2", "CURVEFM_QUOTA_BYTES": "60000"}
    return Lab(module_processes.api(tmp_path_factory.mktemp("limited") / "data", env=env))


def session_ids(client: httpx.Client) -> set[str]:
    return {s["id"] for s in client.get("/sessions").raise_for_status().json()}


def test_a_user_removed_and_added_again_sees_nothing_of_the_old_ones(lab):
    old = lab.api.client_for("rita")
    session_id = lab.new_session(old, name="rita's private")
    assert session_id in session_ids(old)
    users_of(lab.api.data_dir).remove("rita")
    assert old.get("/sessions").status_code == 401

    new = lab.api.client_for("rita")  # the same name, another user
    assert session_id not in session_ids(new)
    expect(new.get(f"/sessions/{session_id}"), 404, "not_found")
    expect(new.delete(f"/sessions/{session_id}"), 404, "not_found")
    record = lab.admin.get(f"/sessions/{session_id}").raise_for_status().json()
    assert record["owner"] == "rita (removed)"  # the old owner, whom no current user can be


def test_a_shape_in_use_cannot_be_deleted_and_the_409_names_what_uses_it(lab):
    shape = lab.new_shape()
    lab.basis(lab.owner, shape)
    session_id = lab.new_session(source=shape, target=lab.shapes[1])
    refused = expect(lab.owner.delete(f"/shapes/{shape}"), 409, "conflict", f"session {session_id}")
    assert len(refused["detail"]) < 500
    assert lab.owner.get(f"/shapes/{shape}").status_code == 200  # nothing was deleted
    lab.owner.delete(f"/sessions/{session_id}").raise_for_status()
    assert lab.owner.delete(f"/shapes/{shape}").status_code == 204
    expect(lab.owner.get(f"/shapes/{shape}"), 404, "not_found")


def test_the_sessions_quota_refuses_the_next_and_stores_nothing(limited):
    client = limited.api.client_for("quinn")
    made = [limited.new_session(client) for _ in range(2)]
    body = {"source": limited.shapes[0], "target": limited.shapes[1], "k": 10}
    expect(client.post("/sessions", json=body), 429, "too_many", "CURVEFM_QUOTA_SESSIONS")
    assert session_ids(client) == set(made)
    client.delete(f"/sessions/{made[0]}").raise_for_status()
    assert limited.new_session(client) not in made  # a deleted session no longer counts


def test_an_upload_over_the_byte_quota_stores_nothing(limited):
    client = limited.api.client_for("bea")
    big = ellipsoid(60, 120)
    before = {p.name for p in (limited.api.data_dir / "meshes").iterdir()}
    refused = client.post("/shapes", files={"file": ("big.off", off_bytes(big))})
    expect(refused, 413, "too_large", "CURVEFM_QUOTA_BYTES")
    assert {p.name for p in (limited.api.data_dir / "meshes").iterdir()} == before
    assert len(client.get("/shapes").raise_for_status().json()) == len(limited.shapes)


def test_edits_of_one_session_through_two_api_processes_are_all_kept(lab, module_processes):
    """Two API processes on one database, four threads adding curves to one session at once: every acknowledged
    edit is kept, with a unique id."""
    second = module_processes.api(lab.api.data_dir)
    session_id = lab.new_session()
    clients = [httpx.Client(base_url=api.url, timeout=120, headers=bearer(lab.api.token)) for api in (lab.api, second)]
    acknowledged: list[str] = []
    failures: list[str] = []

    def add(worker: int) -> None:
        for _ in range(5):
            edit = clients[worker % 2].post(f"/sessions/{session_id}/curves", json=CURVE)
            if edit.status_code == 201:
                acknowledged.append(edit.json()["curve"]["id"])
            else:
                failures.append(edit.text)

    threads = [threading.Thread(target=add, args=(worker,)) for worker in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not failures, failures[:3]
    stored = [c["id"] for c in lab.owner.get(f"/sessions/{session_id}").raise_for_status().json()["curves"]]
    assert sorted(stored) == sorted(acknowledged) and len(set(stored)) == len(stored) == 20


def test_health_reports_the_database(lab, module_database):
    health = lab.anonymous.get("/health").raise_for_status().json()
    assert health["database"] == module_database


@pytest.mark.sqlite_only
def test_a_database_file_that_is_not_curvefms_stops_the_start(tmp_path, module_database):
    if module_database != "sqlite":
        pytest.skip("the SQLite file of a data directory")
    (tmp_path / "curvefm.db").write_bytes(b"not a database " * 1000)
    started = subprocess.run(
        [sys.executable, "-m", "curvefm.service", "--port", "0", "--data", str(tmp_path)],
        env={**os.environ, "CURVEFM_DATABASE_URL": ""},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert started.returncode == 1 and "is not a curvefm database" in started.stderr, started.stderr
    assert "Traceback" not in started.stderr
    assert (tmp_path / "curvefm.db").read_bytes() == b"not a database " * 1000  # left alone


def test_the_first_start_imports_the_old_layout_and_says_so(processes, tmp_path):
    data = tmp_path / "data"
    old = write_legacy(data)
    api = processes.api(data, user=None)  # a new data directory's database (on PostgreSQL too): a first start
    check_imported(api, old)


def check_imported(api, old) -> None:
    alice = httpx.Client(base_url=api.url, timeout=120, headers=bearer(old.tokens["alice"]))
    mine = {s for s, record in old.sessions.items() if record.owner == "alice"}
    assert mine and mine <= session_ids(alice)
    assert "imported" in api.log.read_text()
    for session_id in mine:
        record = alice.get(f"/sessions/{session_id}").raise_for_status().json()
        assert len(record["curves"]) == len(old.sessions[session_id].curves)


def test_the_sessions_list_pages_with_the_total(lab):
    client = lab.api.client_for("pam")
    made = [lab.new_session(client, name=f"pam {i}") for i in range(3)]
    first = client.get("/sessions", params={"limit": 2})
    assert first.status_code == 200 and first.headers["X-Total-Count"] == "3"
    second = client.get("/sessions", params={"limit": 2, "offset": 2}).raise_for_status()
    paged = [s["id"] for s in first.json() + second.json()]
    assert paged == made[::-1]  # the most recently changed first
    assert [s["id"] for s in client.get("/sessions").json()] == paged
    expect(client.get("/sessions", params={"limit": 0}), 422, "invalid")


# -- collections ---------------------------------------------------------------------------------------------
def new_collection(lab: Lab, client: httpx.Client, members: list[str], template: str | None = None):
    body = {"template": template or lab.shapes[0], "members": members, "k": 10, "curves": [{"waypoints": [0, 60]}]}
    return client.post("/collections", json=body)


def test_deleting_a_member_session_leaves_the_collection_readable_without_it(lab):
    made = new_collection(lab, lab.owner, [lab.shapes[1], lab.new_shape()])  # a shape is a member once
    assert made.status_code == 201, made.text
    collection = made.json()["collection"]
    gone, kept = collection["members"]
    lab.owner.delete(f"/sessions/{gone['session']}").raise_for_status()
    view = lab.owner.get(f"/collections/{collection['id']}").raise_for_status().json()
    assert [m["id"] for m in view["collection"]["members"]] == [kept["id"]]
    assert view["collection"]["revision"] > collection["revision"]


def test_a_shape_used_by_a_collection_cannot_be_deleted(lab):
    template = lab.new_shape()
    made = new_collection(lab, lab.owner, [], template=template)
    assert made.status_code == 201, made.text
    collection_id = made.json()["collection"]["id"]
    expect(lab.owner.delete(f"/shapes/{template}"), 409, "conflict", f"collection {collection_id}")
    assert lab.owner.get(f"/shapes/{template}").status_code == 200


def test_collections_count_in_the_sessions_quota_and_a_refused_one_stores_nothing(limited):
    client = limited.api.client_for("cora")
    shapes = [limited.shapes[1], limited.new_shape(), limited.new_shape()]  # a shape is a member once
    expect(new_collection(limited, client, shapes), 429, "too_many", "CURVEFM_QUOTA_SESSIONS")
    assert client.get("/collections").json() == [] and session_ids(client) == set()
    made = new_collection(limited, client, shapes[:2])
    assert made.status_code == 201, made.text
    body = {"source": limited.shapes[0], "target": limited.shapes[1], "k": 10}
    expect(client.post("/sessions", json=body), 429, "too_many", "CURVEFM_QUOTA_SESSIONS")
    collection_id = made.json()["collection"]["id"]
    members = client.post(f"/collections/{collection_id}/members", json={"shapes": [shapes[2]]})
    expect(members, 429, "too_many", "CURVEFM_QUOTA_SESSIONS")
    before = {p.name for p in (limited.api.data_dir / "meshes").iterdir()}
    upload = {"files": ("new.off", off_bytes(ellipsoid(8, 16, scale=1.5)))}
    expect(client.post(f"/collections/{collection_id}/members/upload", files=upload), 429, "too_many")
    assert {p.name for p in (limited.api.data_dir / "meshes").iterdir()} == before  # the refused upload stored nothing


def test_a_run_whose_jobs_expired_still_answers_and_says_so(processes, tmp_path):
    env = {"CURVEFM_JOB_TTL": "2", "CURVEFM_EXPIRY_INTERVAL": "0.5"}
    lab = Lab(processes.api(tmp_path / "data", env=env))
    made = new_collection(lab, lab.owner, [lab.shapes[1]])
    assert made.status_code == 201, made.text
    collection = made.json()["collection"]
    base = f"/collections/{collection['id']}"
    member = collection["members"][0]["id"]
    answer = {"template_curve": "t1", "target": [0, 60]}
    lab.owner.post(f"{base}/members/{member}/curves", json=answer).raise_for_status()
    run = lab.owner.post(f"{base}/runs", json={}).raise_for_status().json()
    job_id = run["members"][0]["job"]
    assert lab.wait_job(lab.owner, job_id)["state"] == "finished"
    deadline = time.monotonic() + 30
    while lab.owner.get(f"/jobs/{job_id}").status_code != 404:
        assert time.monotonic() < deadline, "the job did not expire"
        time.sleep(0.25)
    status = lab.owner.get(f"{base}/runs/{run['id']}").raise_for_status().json()
    assert status["members"][0]["state"] == "lost" and "expired" in status["members"][0]["message"]
    assert lab.owner.get(base).status_code == 200
