"""Limits and hardening over HTTP, on real server processes (and real Redis and workers where the queue matters):
quotas, the rate limit (shared by two API processes), the Host check, security headers, no paths or tokens
leaking, the admins' audit route, and expiry of jobs and their result files."""

from __future__ import annotations

import os
import subprocess
import sys
import time
import uuid
from pathlib import Path

import httpx
import pytest
from support.ci import unavailable
from support.errors import expect as error_body
from support.records import database_env
from support.ui import CHROMIUM, launch

from curvefm.access import users_of
from curvefm.geometry import load_mesh, save_mesh
from curvefm.service.demo import demo_shapes
from curvefm.service.quotas import stored_bytes
from curvefm.workers.job_rows import DbJobRecords

K = 20
SECURITY_HEADERS = ("x-content-type-options", "x-frame-options", "referrer-policy", "content-security-policy")


def add_users(data: Path, *names: str, admin: str | None = None) -> dict[str, str]:
    """Tokens of new users ``names`` (and of a new admin), made in the data directory's database before the server
    starts."""
    users = users_of(data)
    tokens = {name: users.add(name) for name in names}
    if admin:
        tokens[admin] = users.add(admin, admin=True)
    return tokens


def as_user(api, token: str) -> httpx.Client:
    return httpx.Client(base_url=api.url, timeout=120, headers={"Authorization": f"Bearer {token}"})


def demo_files(folder: Path) -> list[Path]:
    paths = []
    for mesh in demo_shapes():
        paths.append(folder / f"{mesh.name}.off")
        save_mesh(mesh, paths[-1])
    return paths


def upload(client: httpx.Client, path: Path) -> httpx.Response:
    with open(path, "rb") as f:
        return client.post("/shapes", files={"file": (path.name, f)})


def wait_job(client: httpx.Client, job_id: str, timeout: float = 120) -> dict:
    deadline = time.monotonic() + timeout
    while (info := client.get(f"/jobs/{job_id}").raise_for_status().json())["state"] not in (
        "finished",
        "failed",
        "canceled",
        "lost",
    ):
        assert time.monotonic() < deadline, info
        time.sleep(0.1)
    return info


# -- quotas ----------------------------------------------------------------------------------------------------
def test_quotas_answer_413_and_429_naming_the_limit(processes, redis_url, redis_prefix, tmp_path):
    """Bytes (413), concurrent jobs and sessions (429); admins are exempt. Redis mode: jobs wait for a worker,
    so 'queued' lasts until the test starts one."""
    files = demo_files(tmp_path)
    one_shape = stored_bytes(load_mesh(files[0]))
    tokens = add_users(tmp_path / "data", "alice", admin="root")
    env = {
        "CURVEFM_QUEUE_PREFIX": redis_prefix,
        "CURVEFM_QUOTA_BYTES": str(one_shape * 3 // 2),
        "CURVEFM_QUOTA_JOBS": "1",
        "CURVEFM_QUOTA_SESSIONS": "1",
    }
    api = processes.api(tmp_path / "data", redis_url, env=env)
    alice, root = as_user(api, tokens["alice"]), as_user(api, tokens["root"])

    first = upload(alice, files[0])
    assert first.status_code == 201, first.text
    body = error_body(upload(alice, files[1]), 413, "too_large", "CURVEFM_QUOTA_BYTES", str(one_shape * 3 // 2))
    assert body["limit"] == "CURVEFM_QUOTA_BYTES"
    assert upload(alice, files[0]).status_code == 200  # her own shape again: nothing new is stored
    exempt = upload(root, files[1])  # admins are exempt
    assert exempt.status_code == 201, exempt.text
    ids = [first.json()["id"], exempt.json()["id"]]

    queued = alice.post(f"/shapes/{ids[0]}/bases", json={"k": K}).raise_for_status().json()
    body = error_body(alice.post(f"/shapes/{ids[1]}/bases", json={"k": K}), 429, "too_many", "CURVEFM_QUOTA_JOBS")
    assert body["limit"] == "CURVEFM_QUOTA_JOBS"
    assert root.post(f"/shapes/{ids[1]}/bases", json={"k": K}).status_code == 202
    processes.worker(redis_url, redis_prefix, "quota-worker")
    assert wait_job(alice, queued["id"])["state"] == "finished"
    second = alice.post(f"/shapes/{ids[1]}/bases", json={"k": K})  # one job at a time: the first one ended
    assert second.status_code == 202, second.text
    assert wait_job(alice, second.json()["id"])["state"] == "finished"

    session = {"source": ids[0], "target": ids[1], "k": K}
    assert alice.post("/sessions", json=session).status_code == 201
    body = error_body(alice.post("/sessions", json=session), 429, "too_many", "CURVEFM_QUOTA_SESSIONS")
    assert body["limit"] == "CURVEFM_QUOTA_SESSIONS"
    assert [root.post("/sessions", json=session).status_code for _ in range(2)] == [201, 201]


# -- rate limit ------------------------------------------------------------------------------------------------
def test_rate_limit_answers_429_with_retry_after_per_token(processes, tmp_path):
    tokens = add_users(tmp_path / "data", "alice", "bob")
    env = {"CURVEFM_RATE_LIMIT": "0.5", "CURVEFM_RATE_BURST": "3"}
    api = processes.api(tmp_path / "data", env=env)
    alice, bob = as_user(api, tokens["alice"]), as_user(api, tokens["bob"])

    statuses = [alice.get("/plugins").status_code for _ in range(4)]
    assert statuses[:3] == [200, 200, 200] and statuses[3] == 429, statuses
    limited = alice.get("/shapes")
    body = error_body(limited, 429, "too_many", "CURVEFM_RATE_LIMIT", "CURVEFM_RATE_BURST")
    assert body["limit"] == "CURVEFM_RATE_LIMIT"
    retry_after = int(limited.headers["retry-after"])
    assert 1 <= retry_after <= 2
    assert bob.get("/plugins").status_code == 200  # another token, another bucket
    assert {alice.get(path).status_code for path in ["/health", "/", "/app.js"] * 5} == {200}  # never limited
    time.sleep(retry_after)
    assert alice.get("/plugins").status_code == 200


def test_made_up_credentials_share_their_address_allowance(processes, tmp_path):
    """Cookies or tokens that change with every request get no fresh allowance each: until a credential has
    authenticated, its requests count against the client's address; a real user keeps their own allowance."""
    tokens = add_users(tmp_path / "data", "alice")
    rate, burst, sent = 0.5, 5, 30
    api = processes.api(tmp_path / "data", env={"CURVEFM_RATE_LIMIT": str(rate), "CURVEFM_RATE_BURST": str(burst)})
    port = api.url.rsplit(":", 1)[1]
    anonymous = httpx.Client(base_url=api.url, timeout=120)
    started = time.monotonic()
    statuses = []
    for i in range(sent):
        if i % 2:
            headers = {"Cookie": f"junk{i}={uuid.uuid4().hex}; curvefm_login_{port}={uuid.uuid4().hex}.x"}
        else:
            headers = {"Authorization": f"Bearer cfm_{uuid.uuid4().hex}"}
        statuses.append(anonymous.get("/sessions", headers=headers).status_code)
    allowed = burst + int((time.monotonic() - started) * rate) + 1
    assert set(statuses) == {401, 429} and statuses.count(401) <= allowed, statuses
    alice = as_user(api, tokens["alice"])
    assert [alice.get("/sessions").status_code for _ in range(burst)] == [200] * burst


def test_a_request_without_credentials_is_a_401_past_the_rate_too(processes, tmp_path):
    """A request with no credential at all can only be told to authenticate (a 401 costs no more than a 429), so
    it is not counted: past the rate it still gets 401, and a user's allowance is untouched by it."""
    tokens = add_users(tmp_path / "data", "alice")
    burst = 3
    api = processes.api(tmp_path / "data", env={"CURVEFM_RATE_LIMIT": "0.5", "CURVEFM_RATE_BURST": str(burst)})
    anonymous = httpx.Client(base_url=api.url, timeout=120)
    answers = [anonymous.get("/sessions") for _ in range(3 * burst)]
    answers += [anonymous.post("/sessions", json={}) for _ in range(3 * burst)]
    assert {answer.status_code for answer in answers} == {401}, [answer.text for answer in answers]
    alice = as_user(api, tokens["alice"])
    assert [alice.get("/sessions").status_code for _ in range(burst)] == [200] * burst


def test_two_api_processes_share_the_rate_limit_through_redis(processes, redis_url, redis_prefix, tmp_path):
    rate, burst = 0.5, 6
    env = {"CURVEFM_QUEUE_PREFIX": redis_prefix, "CURVEFM_RATE_LIMIT": str(rate), "CURVEFM_RATE_BURST": str(burst)}
    apis = [processes.api(tmp_path / "data", redis_url, env=env) for _ in range(2)]
    headers = {"Authorization": f"Bearer {add_users(tmp_path / 'data', 'shared')['shared']}"}
    started = time.monotonic()
    answered = [[], []]
    for i in range(4 * burst):
        api = apis[i % 2]
        answered[i % 2].append(api.client.get("/plugins", headers=headers).status_code)
    elapsed = time.monotonic() - started
    allowed = sum(statuses.count(200) for statuses in answered)
    assert allowed <= burst + int(elapsed * rate) + 1, (answered, elapsed)  # one process alone would allow burst
    assert all(200 in statuses and 429 in statuses for statuses in answered), answered
    assert apis[0].client.get("/plugins").status_code == 200  # without that token: another bucket


# -- Host, headers, leaks --------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def server(module_processes, tmp_path_factory):
    """An embedded-mode API with a user and an admin, and a CLI-made user in the audit log."""
    data = tmp_path_factory.mktemp("limits") / "data"
    tokens = add_users(data, "alice", admin="root")
    cli = [sys.executable, "-m", "curvefm.cli", "users", "add", "carol", "--data", str(data)]
    subprocess.run(cli, check=True, capture_output=True, env={**os.environ, **database_env(data)})
    api = module_processes.api(data, env={"CURVEFM_RATE_LIMIT": ""})  # the default limit, as a browser meets it
    api.data, api.tokens = data, tokens
    return api


def test_a_foreign_host_gets_400(server):
    port = server.url.rsplit(":", 1)[1]
    for host in ("localhost", f"localhost:{port}", "127.0.0.1", f"[::1]:{port}"):
        assert server.client.get("/health", headers={"Host": host}).status_code == 200, host
    for path in ("/health", "/", "/shapes"):
        response = server.client.get(path, headers={"Host": "rebound.attacker.example"})
        error_body(response, 400, "invalid", "rebound.attacker.example", "CURVEFM_ALLOWED_HOSTS")
    for malformed in (f"127.0.0.1:{port}@rebound.attacker.example", "localhost:abc", "localhost:80:80", "a b"):
        error_body(server.client.get("/health", headers={"Host": malformed}), 400, "invalid", "NAME[:PORT]")
    long_host = "a" * 5000 + ".example"
    assert len(server.client.get("/health", headers={"Host": long_host}).text) < 500  # the echo is cut short


def test_forwarded_headers_are_believed_only_from_named_proxies(processes, tmp_path):
    """X-Forwarded-Proto decides whether the login cookie is Secure: from anyone on the host unless
    FORWARDED_ALLOW_IPS names the proxy."""
    headers = {"X-Forwarded-Proto": "https"}
    for env, secure in (({}, False), ({"FORWARDED_ALLOW_IPS": "127.0.0.1"}, True)):
        api = processes.api(tmp_path / f"data-{secure}", env=env)
        response = api.client.post("/auth/login", headers=headers)
        assert response.status_code == 200, response.text
        assert ("secure" in response.headers["set-cookie"].lower()) == secure, response.headers["set-cookie"]


def test_allowed_hosts_option(processes, tmp_path):
    api = processes.api(tmp_path / "data", args=("--allowed-hosts", "127.0.0.1, Lab.Example.org"))
    assert api.client.get("/health", headers={"Host": "lab.example.org:8443"}).status_code == 200
    error_body(api.client.get("/health", headers={"Host": "localhost"}), 400, "invalid", "localhost")
    anyone = processes.api(tmp_path / "data2", args=("--allowed-hosts", "*"))
    assert anyone.client.get("/health", headers={"Host": "anything.example"}).status_code == 200


def test_security_headers_on_ui_and_api_answers(server):
    answers = [
        server.client.get("/"),
        server.client.get("/app.js"),
        server.client.get("/vendor/three/build/three.module.js"),
        server.client.get("/health"),
        server.client.get("/plugins"),
        server.client.get("/shapes/no-such-shape"),
        server.client.get("/health", headers={"Host": "elsewhere.example"}),
    ]
    assert [a.status_code for a in answers] == [200, 200, 200, 200, 200, 404, 400]
    for answer in answers:
        assert all(name in answer.headers for name in SECURITY_HEADERS), (answer.request.url, answer.headers)
        assert answer.headers["x-content-type-options"] == "nosniff"
        assert answer.headers["x-frame-options"] == "DENY"
        assert answer.headers["referrer-policy"] == "no-referrer"
        assert "frame-ancestors 'none'" in answer.headers["content-security-policy"]
    csp = answers[0].headers["content-security-policy"]
    assert "default-src 'self'" in csp and "unsafe-inline" not in csp and "unsafe-eval" not in csp


def test_the_ui_runs_under_its_content_security_policy(server):
    """In Chromium: the page's scripts (import map, modules, three.js) load and nothing violates the policy."""
    if not CHROMIUM.is_file():
        unavailable(f"browser tests need Chromium at {CHROMIUM}")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = launch(playwright)
        page = browser.new_page()
        messages = []
        page.on("console", lambda message: messages.append(message.text))
        page.add_init_script(
            "document.addEventListener('securitypolicyviolation', (e) => "
            "(window.cspViolations = window.cspViolations || []).push(e.violatedDirective + ' ' + e.blockedURI))"
        )
        page.goto(f"{server.url}/?token={server.tokens['alice']}")  # the page logs in, then lists the plugins
        page.wait_for_function("() => window.curvefm !== undefined", timeout=30_000)
        page.wait_for_function("() => document.querySelectorAll('#tracer-select option').length > 0", timeout=30_000)
        violations = page.evaluate("window.cspViolations || []")
        browser.close()
    assert not violations, violations
    assert not [m for m in messages if "Content Security Policy" in m], messages


def test_health_shows_no_path(server, module_database):
    response = server.client.get("/health")
    assert response.status_code == 200
    assert set(response.json()) == {"status", "jobs", "database"} and response.json()["database"] == module_database
    assert str(server.data) not in response.text and "/" not in response.text


def test_a_login_token_stays_out_of_the_server_log(server):
    token = server.tokens["alice"]
    assert server.client.get(f"/?token={token}").status_code == 200
    assert server.client.get(f"/?session=x&token={token}&view=1").status_code == 200
    assert server.client.get("/plugins", headers={"Authorization": f"Bearer {token}"}).status_code == 200
    deadline = time.monotonic() + 10
    while "view=1" not in (log := server.log.read_text()):  # the access log line of the second request
        assert time.monotonic() < deadline, log[-2000:]
        time.sleep(0.1)
    assert token not in log
    assert "/?token=[redacted]" in log and "token=[redacted]&view=1" in log


def test_echoed_ids_are_cut_short(server):
    for path in ("/shapes/" + "f" * 10_000, "/sessions/" + "s" * 10_000, "/jobs/" + "j" * 10_000):
        body = error_body(server.client.get(path), 404, "not_found")
        assert len(body["detail"]) < 300, body["detail"][:300]


# -- audit -----------------------------------------------------------------------------------------------------
def test_the_audit_log_is_for_admins(server):
    root, alice = as_user(server, server.tokens["root"]), as_user(server, server.tokens["alice"])
    events = root.get("/audit").raise_for_status().json()
    assert {"user": "cli", "action": "user.add", "target": "carol"}.items() <= events[-1].items(), events
    assert root.get("/audit", params={"user": "cli", "limit": 1}).json() == events[-1:]
    paged = root.get("/audit", params={"limit": 1, "offset": 1})  # the page before the newest event
    assert paged.json() == events[-2:-1] and paged.headers["X-Total-Count"] == str(len(events))
    assert root.get("/audit", params={"user": "nobody"}).json() == []
    assert root.get("/audit", params={"since": "2999-01-01T00:00:00"}).json() == []
    error_body(root.get("/audit", params={"since": "yesterday"}), 422, "invalid", "since")
    error_body(root.get("/audit", params={"limit": 0}), 422, "invalid", "limit")
    error_body(alice.get("/audit"), 403, "forbidden", "admins")
    assert httpx.get(f"{server.url}/audit").status_code == 401  # no credentials
    assert as_user(server, "cfm_" + "x" * 43).get("/audit").status_code == 401


# -- expiry ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mode", ["embedded", "redis"])
def test_ended_jobs_and_their_result_files_expire(mode, processes, redis_url, redis_prefix, tmp_path):
    ttl = 5
    env = {"CURVEFM_JOB_TTL": str(ttl), "CURVEFM_EXPIRY_INTERVAL": "0.5", "CURVEFM_QUEUE_PREFIX": redis_prefix}
    api = processes.api(tmp_path / "data", redis_url if mode == "redis" else None, env=env)
    if mode == "redis":
        processes.worker(redis_url, redis_prefix, "expiry-worker")
    _, session = api.demo_pair(tmp_path, K)
    api.client.post(f"/sessions/{session}/curves", json={"source": [0, 100], "target": [0, 100]}).raise_for_status()
    job = api.client.post(f"/sessions/{session}/refine", json={}).raise_for_status().json()
    finished = api.wait_job(job["id"])
    assert finished["state"] == "finished", finished
    results, records = tmp_path / "data" / "results" / job["id"], DbJobRecords(tmp_path / "data")
    link = finished["links"]["map_target_to_source.txt"]
    assert api.client.get(link).status_code == 200 and results.is_dir() and records.load(job["id"]) is not None

    deadline = time.monotonic() + ttl + 15
    while (
        results.exists()
        or records.load(job["id"]) is not None
        or api.client.get(f"/jobs/{job['id']}").status_code != 404
    ):
        assert time.monotonic() < deadline, f"job {job['id']} or its files outlived the TTL of {ttl} s"
        time.sleep(0.25)
    error_body(api.client.get(link), 404, "not_found")
    assert api.client.get(f"/sessions/{session}").status_code == 200  # sessions do not expire


def test_partial_files_of_interrupted_writes_are_swept(processes, tmp_path):
    """What a write killed before its rename leaves (``.<name>.<random>.tmp``) goes once it is hours old; a
    recent one may be a write in progress and stays."""
    data = tmp_path / "data"
    stale, recent = data / "meshes" / ".a.npz.k1.tmp", data / "bases" / "a" / ".b.npz.k2.tmp"
    for path in (stale, recent):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"half a mesh")
    hours_ago = time.time() - 7 * 3600
    os.utime(stale, (hours_ago, hours_ago))
    processes.api(data, env={"CURVEFM_EXPIRY_INTERVAL": "0.2"})
    for _ in range(300):
        if not stale.exists():
            break
        time.sleep(0.1)
    assert not stale.exists() and recent.exists()


@pytest.mark.parametrize("value", ["0", "-1", "nan", "fast"])
def test_a_server_refuses_an_invalid_interpreter_lock_switch_interval(tmp_path: Path, value: str):
    """``CURVEFM_GIL_SWITCH_MS`` must be a positive number of milliseconds: anything else stops the server at start
    with one line naming the variable (Python itself would refuse 0 with a traceback)."""
    env = {**os.environ, "CURVEFM_GIL_SWITCH_MS": value}
    started = subprocess.run(
        [sys.executable, "-m", "curvefm.service", "--port", "0", "--data", str(tmp_path)],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert started.returncode == 2, started.stderr
    assert "CURVEFM_GIL_SWITCH_MS" in started.stderr and "Traceback" not in started.stderr
