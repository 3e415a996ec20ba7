"""The queue no one else can drive (issue 11): no pickle crosses Redis, and Redis has a password that the API
and the workers must know. Real redis-server, API and worker processes."""

from __future__ import annotations

import json
import subprocess
import sys
import zlib

import redis
from support.processes import WORKER_COMMAND

from curvefm.geometry import save_mesh
from curvefm.service.demo import demo_shapes


def test_a_job_the_api_enqueues_is_json_in_redis_and_a_worker_runs_it(processes, private_redis, tmp_path):
    api = processes.api(tmp_path / "data", private_redis.url())
    save_mesh(demo_shapes()[0], tmp_path / "shape.off")
    shape_id = api.upload(tmp_path / "shape.off")
    job = api.client.post(f"/shapes/{shape_id}/bases", json={"k": 20}).raise_for_status().json()

    stored = redis.Redis.from_url(private_redis.url()).hgetall(f"rq:job:{job['id']}")
    payload = zlib.decompress(stored[b"data"])  # RQ compresses what its serializer wrote
    assert not payload.startswith(b"\x80"), "the job's data is a pickle"
    function, instance, args, kwargs = json.loads(payload)
    assert function == "curvefm.workers.jobs.compute_basis" and instance is None and args == []
    assert (kwargs["mesh_id"], kwargs["k"]) == (shape_id, 20)
    assert json.loads(stored[b"meta"])["kind"] == "basis"

    processes.worker(private_redis.url(), "", "json-worker")
    finished = api.wait_job(job["id"])
    assert (finished["state"], finished["result"]["k"]) == ("finished", 20), finished
    for log in (api.log, tmp_path / "worker-json-worker.log"):
        assert private_redis.password not in log.read_text()


def run_worker(redis_url: str) -> subprocess.CompletedProcess:
    command = [sys.executable, *WORKER_COMMAND[1:], "--redis-url", redis_url, "--burst"]
    return subprocess.run(command, capture_output=True, text=True, timeout=60)


def test_a_worker_with_a_wrong_password_fails_to_start_with_one_clear_line(private_redis):
    wrong = run_worker(private_redis.url("not-the-password"))
    assert wrong.returncode == 2, wrong.stderr
    assert wrong.stderr.count("\n") == 1 and "Traceback" not in wrong.stderr, wrong.stderr
    assert "refused the password" in wrong.stderr and f"127.0.0.1:{private_redis.port}" in wrong.stderr
    assert "not-the-password" not in wrong.stderr

    missing = run_worker(private_redis.url(""))
    assert missing.returncode == 2, missing.stderr
    assert missing.stderr.count("\n") == 1 and "requires a password" in missing.stderr, missing.stderr


def test_an_api_with_a_wrong_password_fails_to_start_with_one_clear_line(private_redis, tmp_path):
    command = [sys.executable, "-m", "curvefm.service", "--data", str(tmp_path), "--port", "0"]
    result = subprocess.run(
        [*command, "--redis-url", private_redis.url("not-the-password")], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip().startswith("curvefm: error: Redis at") and "refused the password" in result.stderr
    assert result.stderr.count("\n") == 1 and "not-the-password" not in result.stderr
