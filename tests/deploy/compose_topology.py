"""The deployment of docker-compose.yml, running, tested through its proxy only: scripts/test-deploy.sh builds the
images, starts the compose project and runs this file (its name keeps it out of the main suite, which collects
``test_*.py``). A lab day: log in with the token the API printed, upload a shape pair, compute its bases on the
basis worker (restarted mid-job), open a session and add curves (an API replica restarted between two edits),
refine on the refinement worker, download a result file; nothing acknowledged is lost.

Settings, from the script: ``CURVEFM_DEPLOY_URL`` (the proxy), ``CURVEFM_DEPLOY_TOKEN`` (from the login URL in the
API's log), ``CURVEFM_DEPLOY_PROJECT`` (podman-compose's project: containers ``<project>_<service>_1``),
``CURVEFM_DEPLOY_IMAGE`` (the curvefm image) and ``CURVEFM_DEPLOY_REDIS_PASSWORD``.
"""

from __future__ import annotations

import os
import subprocess
import time
from pathlib import Path

import httpx
import numpy as np
import pytest
from support.shapes import save_demo_shapes

from curvefm.client import Client, Job
from curvefm.service.demo import demo_shapes
from curvefm.service.models import ErrorBody

K = 20
CURVES = [([10, 2000], [10, 2000]), ([500, 3500], [500, 3500]), ([100, 4000], [100, 4000])]
"""Waypoints on the demo shapes, which share their vertex ids."""
JOB_TIMEOUT_S = 300


def setting(name: str) -> str:
    value = os.environ.get(name)
    if not value:
        pytest.fail(f"{name} is not set: run this file through scripts/test-deploy.sh", pytrace=False)
    return value


def podman(*args: str, timeout: float = 120) -> str:
    done = subprocess.run(["podman", *args], capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, f"podman {' '.join(args)} failed:\n{done.stderr[-2000:]}"
    return done.stdout


def container(service: str) -> str:
    return f"{setting('CURVEFM_DEPLOY_PROJECT')}_{service}_1"


def status(service: str) -> str:
    return podman("inspect", "--format", "{{.State.Status}}", container(service)).strip()


def until_healthy(service: str) -> None:
    """Run the service's own healthcheck (compose's) until it passes: podman runs it only from systemd timers.
    Once a second: each check starts a Python in the container, and a host kept busy by them answers the proxy's
    own health checks late."""
    deadline = time.monotonic() + 120
    while subprocess.run(["podman", "healthcheck", "run", container(service)], capture_output=True).returncode:
        assert time.monotonic() < deadline, f"{service} is not healthy 2 minutes after its restart"
        time.sleep(1)


def restart(service: str) -> None:
    """``podman restart`` of one service's container: SIGTERM, 10 s, then SIGKILL, as an operator's restart."""
    podman("restart", container(service))


def until_started(job: Job) -> None:
    """Wait until a worker has taken the job (or it has ended already: the small jobs are quick)."""
    deadline = time.monotonic() + JOB_TIMEOUT_S
    while job.state == "queued":
        assert time.monotonic() < deadline, f"no worker took job {job.id} in {JOB_TIMEOUT_S} s"
        time.sleep(0.1)


@pytest.fixture(scope="module")
def client():
    with Client(setting("CURVEFM_DEPLOY_URL"), token=setting("CURVEFM_DEPLOY_TOKEN")) as client:
        yield client


@pytest.fixture(scope="module")
def shape_files(tmp_path_factory) -> list[Path]:
    return save_demo_shapes(tmp_path_factory.mktemp("shapes"))


@pytest.fixture(scope="module")
def shape_ids(client, shape_files) -> list[str]:
    ids = [client.upload(path) for path in shape_files]
    assert len(set(ids)) == 2, f"two different shapes gave the ids {ids}"
    return ids


@pytest.fixture(scope="module")
def bases(client, shape_ids) -> list[dict]:
    """Both bases, computed on the basis worker, which is restarted once it has started the first (SIGTERM: RQ's
    warm shutdown, SIGKILL 10 s later: the job is then retried)."""
    jobs = [client.basis(shape_id, k=K) for shape_id in shape_ids]
    until_started(jobs[0])
    restart("worker-basis")
    return [job.wait(timeout=JOB_TIMEOUT_S, progress=False).info for job in jobs]


def test_the_image_runs_the_cli_and_its_eigensolver_factors_with_cholmod(shape_files):
    image = setting("CURVEFM_DEPLOY_IMAGE")
    assert "usage: curvefm" in podman("run", "--rm", image, "curvefm", "--help")
    # the switch the eigensolver itself makes (curvefm.spectral.eigensolver: CHOLMOD when scikit-sparse imports)
    check = "from curvefm.spectral import eigensolver as e; print('cholmod' if e.cholmod is not None else 'superlu')"
    assert podman("run", "--rm", image, "python", "-c", check).strip() == "cholmod", "the image falls back to SuperLU"
    shape_files[0].parent.chmod(0o755)  # the image's user (uid 1000) reads it
    mount = f"{shape_files[0].parent}:/shapes:ro"
    basis = podman("run", "--rm", "-v", mount, image, "curvefm", "basis", f"/shapes/{shape_files[0].name}", "--k", "30")
    assert "30 eigenpairs of" in basis, basis


def test_redis_keeps_jobs_and_never_evicts_them():
    password = setting("CURVEFM_DEPLOY_REDIS_PASSWORD")
    ask = ["exec", container("redis"), "redis-cli", "--no-auth-warning", "-a", password, "config", "get"]
    assert podman(*ask, "maxmemory-policy").split() == ["maxmemory-policy", "noeviction"]
    assert podman(*ask, "appendonly").split() == ["appendonly", "yes"]
    unauthenticated = ["exec", container("redis"), "redis-cli", "ping"]
    assert "NOAUTH" in podman(*unauthenticated), "Redis answers without its password"


def test_the_proxy_serves_health_and_the_login_url_logs_in():
    url = setting("CURVEFM_DEPLOY_URL")
    health = httpx.get(f"{url}/health", timeout=10)
    assert health.status_code == 200, health.text
    assert health.json().get("database") == "postgresql", health.json()
    with httpx.Client(base_url=url, timeout=10) as browser:  # what the page does with the login URL's ?token=
        assert browser.get("/").status_code == 200
        login = browser.post("/auth/login", headers={"Authorization": f"Bearer {setting('CURVEFM_DEPLOY_TOKEN')}"})
        assert login.status_code == 200 and browser.cookies, f"logging in gave {login.status_code}: {login.text}"
        assert browser.get("/auth/me").json()["name"] == "admin"


def test_bases_are_computed_by_the_basis_worker_despite_its_restart(bases):
    assert [basis["state"] for basis in bases] == ["finished", "finished"], bases


def test_a_session_keeps_every_curve_across_an_api_restart_and_refines_on_the_workers(client, shape_ids, bases):
    session = client.session(*shape_ids, k=K)
    first = session.add_curve(*CURVES[0])
    restart("api")
    # once it answers again: Caddy 2.6 does not retry a POST that met the replica while it restarted (502, nothing
    # changed; deploy/Caddyfile), and the point here is that no acknowledged edit is lost
    until_healthy("api")
    later = [session.add_curve(source, target) for source, target in CURVES[1:]]
    assert [c.id for c in client.open_session(session.id).curves] == [first.id, *(c.id for c in later)]

    refinement = session.refine("nearest-neighbor")
    until_started(refinement)
    restart("worker-refine")
    result = refinement.wait(timeout=JOB_TIMEOUT_S, progress=False)
    assert result.revision == session.refresh()["revision"]
    text = client.download(result.files["map_target_to_source.txt"]).decode()
    assert np.array_equal(np.loadtxt(text.splitlines(), dtype=int), result.map_target_to_source)
    assert len(result.map_target_to_source) == len(demo_shapes()[1].file_ids)


def test_the_api_replicas_both_answer_after_the_restarts(client):
    """Caddy balances round robin: a run of requests reaches both replicas, each of which reads the same records."""
    deadline = time.monotonic() + 60
    while (states := [status(name) for name in ("api", "api-2")]) != ["running", "running"]:
        assert time.monotonic() < deadline, f"the API replicas are {states} a minute after the restarts"
        time.sleep(1)
    totals = {client.page("/sessions", limit=1)[1] for _ in range(6)}
    assert totals == {1}, f"the replicas disagree on the number of sessions: {totals}"


def test_with_no_replica_up_the_proxy_answers_503_in_the_error_schema_with_retry_after():
    """Both replicas down (an upgrade, or both left out by a failed health check on a loaded host): the request
    reached no replica, so the proxy says when to send it again, in the API's own error schema (deploy/Caddyfile)."""
    url = setting("CURVEFM_DEPLOY_URL")
    for name in ("api", "api-2"):
        podman("stop", container(name))
    try:
        deadline = time.monotonic() + 60
        while (health := httpx.get(f"{url}/health", timeout=30)).status_code != 503:
            assert time.monotonic() < deadline, f"the proxy still answers {health.status_code} with no replica up"
            time.sleep(1)
        answer = httpx.post(f"{url}/sessions", json={}, timeout=30)
        assert answer.status_code == 503, answer.text
        assert answer.headers["retry-after"] == "5", answer.headers
        assert ErrorBody.model_validate(answer.json()).error == "unavailable"
    finally:
        for name in ("api", "api-2"):
            podman("start", container(name))
        for name in ("api", "api-2"):
            until_healthy(name)
