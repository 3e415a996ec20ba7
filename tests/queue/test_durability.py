"""No job lost without a trace (issue 12): a job the queue lost (Redis restarted empty, an embedded-mode API
restarted) is reported ``lost`` with a reason and runs again on retry; while Redis is down the job endpoints
answer 503 with Retry-After and everything else keeps working. Real redis-server, API and worker processes;
the Redis each test stops is its own (never the shared one)."""

from __future__ import annotations

import time

import pytest

from curvefm.geometry import save_mesh
from curvefm.service.demo import demo_shapes
from curvefm.workers.interface import JobInfo
from curvefm.workers.job_rows import DbJobRecords, StoredJob

SLOW_K = 500  # a FAUST basis this large takes 5-15 s: long enough to kill the API while it runs


def upload_demo_shape(api, folder) -> str:
    save_mesh(demo_shapes()[0], folder / "shape.off")
    return api.upload(folder / "shape.off")


def request_basis(api, shape_id: str, k: int) -> dict:
    response = api.client.post(f"/shapes/{shape_id}/bases", json={"k": k})
    assert response.status_code == 202, response.text
    return response.json()


def expect_lost(api, job_id: str, cause: str, doing: str) -> dict:
    response = api.client.get(f"/jobs/{job_id}")
    assert response.status_code == 200, response.text
    job = response.json()
    assert job["state"] == "lost", job
    assert cause in job["message"] and f"while the job was {doing}" in job["message"], job
    assert f"POST /jobs/{job_id}/retry" in job["message"]
    assert job["error"] == {"kind": "lost", "message": job["message"]}, job  # where a client looks for failures
    return job


def test_a_job_lost_with_an_emptied_redis_is_reported_lost_and_a_retry_runs_it(processes, private_redis, tmp_path):
    api = processes.api(tmp_path / "data", private_redis.url())
    shape_id = upload_demo_shape(api, tmp_path)
    queued = request_basis(api, shape_id, 20)  # no worker yet: it stays queued
    assert queued["state"] == "queued"

    private_redis.stop()
    private_redis.start()  # empty, as compose's Redis without persistence came back

    expect_lost(api, queued["id"], "Redis", "queued")
    assert api.client.get("/jobs/0123456789abcdef0123456789abcdef").status_code == 404  # never issued
    assert api.client.delete(f"/jobs/{queued['id']}").status_code == 409
    retried = api.client.post(f"/jobs/{queued['id']}/retry")
    assert retried.status_code == 202, retried.text
    retry = retried.json()
    assert retry["id"] != queued["id"] and (retry["kind"], retry["state"]) == ("basis", "queued")
    assert api.client.post(f"/jobs/{queued['id']}/retry").json()["id"] == retry["id"]  # while it is queued
    assert request_basis(api, shape_id, 20)["id"] == retry["id"]  # and the same request again

    processes.worker(private_redis.url(), "", "after-restart")
    finished = api.wait_job(retry["id"])
    assert (finished["state"], finished["result"]["k"]) == ("finished", 20), finished
    assert finished["links"] == {"shape": f"/shapes/{shape_id}"}
    assert [b["k"] for b in api.client.get(f"/shapes/{shape_id}").json()["bases"]] == [20]
    assert api.client.post(f"/jobs/{retry['id']}/retry").status_code == 409  # finished: nothing to retry

    private_redis.stop()
    private_redis.start()  # emptied again: a finished job is still answered, from its record
    assert api.client.get(f"/jobs/{retry['id']}").json() == finished
    assert api.client.get(f"/jobs/{queued['id']}").json()["state"] == "lost"


def test_jobs_interrupted_by_an_embedded_mode_restart_are_lost_and_a_retry_runs_them(processes, tmp_path, shared_data):
    data = tmp_path / "data"
    api = processes.api(data)
    shape_id = api.upload(shared_data / "faust" / "tr_reg_000.off")
    running = [request_basis(api, shape_id, k) for k in (SLOW_K, SLOW_K - 1)]  # both executor threads
    queued = request_basis(api, shape_id, 20)
    assert api.wait_job(running[0]["id"], until=("started",))["state"] == "started"
    assert api.client.get(f"/jobs/{queued['id']}").json()["state"] == "queued"
    processes.kill(api.process)

    restarted = processes.api(data)
    for job in running:
        expect_lost(restarted, job["id"], "the service restarted", "running")
    expect_lost(restarted, queued["id"], "the service restarted", "queued")
    retry = restarted.client.post(f"/jobs/{queued['id']}/retry").raise_for_status().json()
    finished = restarted.wait_job(retry["id"])
    assert (finished["state"], finished["result"]["k"]) == ("finished", 20), finished
    assert restarted.client.get(f"/jobs/{queued['id']}").json()["state"] == "lost"  # the original stays lost


def test_while_redis_is_down_jobs_answer_503_and_edits_maps_and_transfers_go_on(processes, private_redis, tmp_path):
    api = processes.api(tmp_path / "data", private_redis.url())
    processes.worker(private_redis.url(), "", "w1")
    (source, _), session_id = api.demo_pair(tmp_path, 30)
    finished_job = request_basis(api, source, 30)["id"]  # the basis exists: it finishes at once
    assert api.wait_job(finished_job)["state"] == "finished"
    curve = {"source": [0, 1000], "target": [0, 1000]}
    assert api.client.post(f"/sessions/{session_id}/curves", json=curve).status_code == 201

    private_redis.stop()

    for method, path, body in [
        ("GET", f"/jobs/{finished_job}", None),
        ("DELETE", f"/jobs/{finished_job}", None),
        ("POST", f"/jobs/{finished_job}/retry", None),
        ("POST", f"/shapes/{source}/bases", {"k": 40}),
        ("POST", f"/sessions/{session_id}/refine", {"converter": "nearest-neighbor"}),
        ("GET", "/health", None),
    ]:
        started = time.monotonic()
        response = api.client.request(method, path, json=body)
        assert response.status_code == 503, (method, path, response.text)
        assert time.monotonic() - started < 5, f"{method} {path} waited for Redis"
        assert int(response.headers["Retry-After"]) > 0
        error = response.json()
        assert error["error"] == "unavailable" and "Redis" in error["detail"], error
        assert private_redis.password not in response.text and str(private_redis.port) not in response.text

    target = api.client.get(f"/sessions/{session_id}").json()["target"]
    created = api.client.post("/sessions", json={"source": source, "target": target, "k": 30})
    assert created.status_code == 201, created.text  # quotas are counted in the database, not asked of Redis
    edit = api.client.post(f"/sessions/{session_id}/curves", json={"source": [5, 2000], "target": [5, 2000]})
    assert edit.status_code == 201, edit.text
    assert edit.json()["map"]["n_curves"] == 2
    the_map = api.client.get(f"/sessions/{session_id}/map")
    assert the_map.status_code == 200 and the_map.json()["revision"] == edit.json()["map"]["revision"]
    transfer = api.client.get(f"/sessions/{session_id}/transfer", params={"function": "xyz"})
    assert transfer.status_code == 200 and transfer.headers["X-Shape"] == "4098,3"

    private_redis.start()  # back, empty: the service answers again and knows its finished job from its record
    assert api.client.get("/health").status_code == 200
    assert api.client.get(f"/jobs/{finished_job}").json()["state"] == "finished"


@pytest.fixture
def records(tmp_path) -> DbJobRecords:
    records = DbJobRecords(tmp_path)
    records.create(StoredJob(JobInfo("j1", "basis", "queued"), {"data_dir": str(tmp_path), "k": 20}, "basis:x"))
    return records


def test_a_lost_record_is_not_revived_by_a_late_worker_but_may_be_finished_by_it(records):
    records.update("j1", state="started", worker="w")
    assert records.lose("j1", "Redis restarted").state == "lost"
    assert records.update("j1", state="started").state == "lost"
    assert records.update("j1", progress=0.5, message="computing").message == "Redis restarted"
    assert records.update("j1", state="finished", result={"k": 20}).state == "finished"
    assert records.lose("j1", "again").state == "finished"  # an ended job is never declared lost
    stored = records.load("j1")
    assert (stored.kwargs["k"], stored.dedupe_key, stored.info.result) == (20, "basis:x", {"k": 20})
    assert records.load("../j1") is None and records.load("nope") is None
