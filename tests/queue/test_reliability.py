"""RQ mode with real Redis and real worker processes: a worker killed with SIGKILL mid-job never loses the job
(another worker retries it, or it fails with a reason), and a running job can be canceled."""

from __future__ import annotations

import time

import pytest

SLOW_K = 500  # a FAUST basis this large takes 5-15 s (k = 150 took 0.6 s on a quiet machine): time to kill its worker


@pytest.fixture
def faust_shape(shared_data):
    return shared_data / "faust" / "tr_reg_000.off"


def start_api(processes, tmp_path, redis_url, prefix, retries: int):
    env = {"CURVEFM_QUEUE_PREFIX": prefix, "CURVEFM_JOB_RETRIES": str(retries)}
    return processes.api(tmp_path / "data", redis_url, env=env)


def start_slow_job(api, mesh_path) -> tuple[str, dict]:
    """Queue a slow basis job and wait until a worker runs it."""
    shape_id = api.upload(mesh_path)
    job = api.client.post(f"/shapes/{shape_id}/bases", json={"k": SLOW_K}).raise_for_status().json()
    info = api.wait_job(job["id"], until=("started", "finished", "failed", "canceled"))
    assert info["state"] == "started", info
    time.sleep(1.0)
    info = api.client.get(f"/jobs/{job['id']}").json()
    assert info["state"] == "started", f"the job ended before its worker could be killed: {info}"
    return shape_id, info


def test_job_of_a_killed_worker_is_retried_by_another(processes, tmp_path, redis_url, redis_prefix, faust_shape):
    workers = {
        f"{redis_prefix}{name}": processes.worker(redis_url, redis_prefix, name, tmp_path / "data")
        for name in ("w1", "w2")
    }
    api = start_api(processes, tmp_path, redis_url, redis_prefix, retries=1)
    shape_id, running = start_slow_job(api, faust_shape)

    processes.kill(workers[running["worker"]])
    final = api.wait_job(running["id"], timeout=180)

    assert final["state"] == "finished", final
    assert final["worker"] != running["worker"]
    assert any(b["k"] >= SLOW_K for b in api.client.get(f"/shapes/{shape_id}").json()["bases"])


def test_job_of_a_killed_worker_fails_with_a_reason_when_no_retry_is_left(
    processes, tmp_path, redis_url, redis_prefix, faust_shape
):
    worker = processes.worker(redis_url, redis_prefix, "only", tmp_path / "data")
    api = start_api(processes, tmp_path, redis_url, redis_prefix, retries=0)
    shape_id, running = start_slow_job(api, faust_shape)

    processes.kill(worker)
    final = api.wait_job(running["id"], timeout=60)

    assert final["state"] == "failed", final
    assert final["error"]["kind"] == "worker_lost", final
    assert "died" in final["error"]["message"] and running["worker"] in final["error"]["message"]
    assert "traceback" not in final
    assert api.client.get(f"/shapes/{shape_id}").json()["bases"] == []


def test_running_job_is_canceled(processes, tmp_path, redis_url, redis_prefix, faust_shape):
    processes.worker(redis_url, redis_prefix, "w1", tmp_path / "data")
    api = start_api(processes, tmp_path, redis_url, redis_prefix, retries=1)
    shape_id, running = start_slow_job(api, faust_shape)

    assert api.client.delete(f"/jobs/{running['id']}").raise_for_status().json()["id"] == running["id"]
    final = api.wait_job(running["id"], timeout=30)

    assert final["state"] == "canceled", final
    assert api.client.delete(f"/jobs/{running['id']}").json()["state"] == "canceled"
    quick = api.client.post(f"/shapes/{shape_id}/bases", json={"k": 20}).raise_for_status().json()
    assert api.wait_job(quick["id"])["state"] == "finished", "the worker did not survive the cancel"
