"""Fixtures shared by the test suite."""

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import uuid
from pathlib import Path
from typing import NoReturn

import httpx
import pytest

from curvefm.runtime import limit_blas_threads

REPO = Path(__file__).resolve().parents[1]
limit_blas_threads()  # as the CLI does: the solver threads, not BLAS, use the cores


def in_ci() -> bool:
    return os.environ.get("CI", "").lower() not in ("", "0", "false")


def unavailable(reason: str) -> NoReturn:
    """End a test that lacks something it needs (the shared data, Redis, Chromium, a program): a skip on a
    developer's machine, a failure with the reason under CI (``CI`` set), where nothing may be missing."""
    if in_ci():
        pytest.fail(f"{reason} [CI is set: a missing requirement fails the test]", pytrace=False)
    pytest.skip(reason)


def shared_data_path() -> Path:
    return Path(os.environ.get("CURVEFM_SHARED_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The real meshes with ground truth (../shared/data or $CURVEFM_SHARED_DATA)."""
    path = shared_data_path()
    if not path.is_dir():
        unavailable(f"shared data folder {path} is absent (set CURVEFM_SHARED_DATA)")
    return path


# ----------------------------------------------------------------------------------------------------------
# Service tests: real Redis, real `python -m curvefm.service` / `python -m curvefm.workers` processes.

API_COMMAND = ["python", "-m", "curvefm.service"]
WORKER_COMMAND = ["python", "-m", "curvefm.workers"]
REDIS_URL = os.environ.get("CURVEFM_TEST_REDIS_URL", "redis://127.0.0.1:6379/0")


@pytest.fixture(scope="session")
def redis_url() -> str:
    import redis

    try:
        redis.Redis.from_url(REDIS_URL, socket_connect_timeout=2).ping()
    except redis.RedisError as exc:
        unavailable(f"no Redis at {REDIS_URL} ({exc}); scripts/test.sh starts one")
    return REDIS_URL


@pytest.fixture
def redis_prefix(redis_url: str):
    """A queue-name prefix of this test only; afterwards every Redis key of it (queues, registries, jobs,
    workers, our own keys) is deleted, and nothing else is touched."""
    import redis

    prefix = f"cfmtest-{uuid.uuid4().hex[:10]}-"
    yield prefix
    connection = redis.Redis.from_url(redis_url)
    job_ids = [
        key.decode().split(":")[2]
        for key in connection.scan_iter("rq:job:*", count=1000)
        if key.count(b":") == 2 and (connection.hget(key, "origin") or b"").decode().startswith(prefix)
    ]
    for pattern in [f"*{job_id}*" for job_id in job_ids] + [f"*{prefix}*"]:
        for key in connection.scan_iter(pattern, count=1000):
            connection.delete(key)
    for registry in ("rq:workers", "rq:queues"):
        for member in connection.smembers(registry):
            if prefix.encode() in member:
                connection.srem(registry, member)


TEST_USER = "tester"
"""The user every API fixture's client acts as (not an admin): made on the server's data directory before it starts."""


def bearer(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


def add_user(data_dir: Path, name: str, admin: bool = False) -> str:
    """Make a user on a data directory (the server sees it at once); a user of an earlier server on it gets a new
    token. Returns the token."""
    from curvefm.access import UserStore
    from curvefm.errors import Conflict

    users = UserStore(data_dir)
    try:
        return users.add(name, admin=admin)
    except Conflict:
        return users.rotate(name)


class Api:
    """A running API process and an HTTP client for it, authenticated as :data:`TEST_USER`."""

    def __init__(self, process: subprocess.Popen, url: str, log: Path, data_dir: Path, token: str | None):
        self.process, self.url, self.log, self.data_dir, self.token = process, url, log, data_dir, token
        self.client = httpx.Client(base_url=url, timeout=120, headers=bearer(token) if token else None)

    def client_for(self, name: str, admin: bool = False) -> httpx.Client:
        """A client of another user, made now."""
        return httpx.Client(base_url=self.url, timeout=120, headers=bearer(add_user(self.data_dir, name, admin)))

    def upload(self, path: Path) -> str:
        with open(path, "rb") as f:
            response = self.client.post("/shapes", files={"file": (path.name, f)})
        assert response.status_code in (200, 201), response.text
        return response.json()["id"]

    def demo_pair(self, folder: Path, k: int, suffix: str = ".off") -> tuple[list[str], str]:
        """Upload the two generated demo shapes (4098 vertices, same ids), compute their bases and create a
        session; return the shape ids and the session id."""
        from curvefm.geometry import save_mesh
        from curvefm.service.demo import demo_shapes

        ids = []
        for mesh in demo_shapes():
            save_mesh(mesh, folder / f"{mesh.name}{suffix}")
            ids.append(self.upload(folder / f"{mesh.name}{suffix}"))
            job = self.client.post(f"/shapes/{ids[-1]}/bases", json={"k": k}).raise_for_status().json()
            assert self.wait_job(job["id"])["state"] == "finished"
        session = self.client.post("/sessions", json={"source": ids[0], "target": ids[1], "k": k})
        return ids, session.raise_for_status().json()["id"]

    def wait_job(self, job_id: str, timeout: float = 120, until=("finished", "failed", "canceled", "lost")) -> dict:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            info = self.client.get(f"/jobs/{job_id}").raise_for_status().json()
            if info["state"] in until:
                return info
            time.sleep(0.1)
        raise AssertionError(f"job {job_id} still {info['state']} after {timeout} s: {info}")


class Processes:
    """Starts service processes in their own process groups; kills every one of them at teardown."""

    api_command, worker_command = API_COMMAND, WORKER_COMMAND

    def __init__(self, folder: Path):
        self.folder = folder
        self.started: list[subprocess.Popen] = []
        self.tokens: dict[tuple[Path, str], str] = {}  # one token per user and data directory, for replicas

    def start(
        self, args: list[str], name: str, env: dict[str, str] | None = None, cwd: Path | None = None
    ) -> subprocess.Popen:
        log = self.folder / f"{name}.log"
        process = subprocess.Popen(
            [sys.executable, *args[1:]] if args[0] == "python" else args,
            env={**os.environ, **(env or {})},
            cwd=cwd,
            stdout=open(log, "ab"),  # noqa: SIM115  (the child holds it; closed when the process ends)
            stderr=subprocess.STDOUT,
        )
        self.started.append(process)
        return process

    def api(
        self, data_dir: Path, redis_url: str | None = None, env: dict[str, str] | None = None, args=(), user=TEST_USER
    ) -> Api:
        """An API process on ``data_dir``, with a client of ``user`` (None: no user is made, so the server makes
        its local admin and prints the login URL)."""
        port = free_port()
        args = [*API_COMMAND, "--host", "127.0.0.1", "--port", str(port), "--data", str(data_dir), *args]
        if redis_url:
            args += ["--redis-url", redis_url]
        name = f"api-{port}"
        token = self.token(data_dir, user) if user else None
        # tests drive a server far faster than a person does: no rate limit unless the test sets one
        process = self.start(args, name, {"CURVEFM_RATE_LIMIT": "0", **(env or {})})
        api = Api(process, f"http://127.0.0.1:{port}", self.folder / f"{name}.log", data_dir, token)
        wait_until_healthy(api)
        return api

    def token(self, data_dir: Path, user: str) -> str:
        """The token of ``user`` on ``data_dir``: the one given to an earlier API on it while it still works (two
        processes serving one directory share the user), else a new one."""
        from curvefm.access import UserStore

        token = self.tokens.get((data_dir, user))
        if token is None or UserStore(data_dir).authenticate(token) is None:
            token = self.tokens[(data_dir, user)] = add_user(data_dir, user)
        return token

    def worker(self, redis_url: str, prefix: str, name: str) -> subprocess.Popen:
        args = [*WORKER_COMMAND, "--redis-url", redis_url, "--name", f"{prefix}{name}"]
        return self.start(args, f"worker-{name}", {"CURVEFM_QUEUE_PREFIX": prefix})

    @staticmethod
    def kill(process: subprocess.Popen) -> None:
        """SIGKILL the process and all its descendants, as a crash of its machine would (an RQ work horse
        runs in a process group of its own, so killing the worker's group alone would leave it running)."""
        for pid in [*descendants(process.pid), process.pid]:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        process.wait(timeout=30)

    def stop_all(self) -> None:
        for process in self.started:
            self.kill(process)


def descendants(pid: int) -> list[int]:
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError, IndexError, ValueError):
            fields = stat.read_text().rsplit(")", 1)[1].split()
            children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    found, frontier = [], [pid]
    while frontier:
        frontier = [child for parent in frontier for child in children.get(parent, [])]
        found += frontier
    return found


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until_healthy(api: Api, timeout: float = 60) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if api.process.poll() is not None:
            log = api.log.read_text()[-3000:]
            raise AssertionError(f"the API exited with {api.process.returncode}:\n{log}")
        try:
            if api.client.get("/health", timeout=2).status_code == 200:
                return
        except httpx.TransportError:
            pass
        time.sleep(0.1)
    raise AssertionError(f"the API did not answer within {timeout} s:\n{api.log.read_text()[-3000:]}")


@pytest.fixture
def processes(tmp_path: Path):
    runner = Processes(tmp_path)
    yield runner
    runner.stop_all()


@pytest.fixture(scope="module")
def module_processes(tmp_path_factory):
    """Like ``processes``, shared by the tests of one module (one server for many quick requests)."""
    runner = Processes(tmp_path_factory.mktemp("processes"))
    yield runner
    runner.stop_all()


class RedisServer:
    """A redis-server of one test, on a free port (never the shared Redis, which other tests use): it can be
    stopped, and restarted empty as docker-compose's Redis without persistence would be."""

    def __init__(self, folder: Path, password: str | None = None):
        self.folder, self.password, self.port = folder, password, free_port()
        self.process: subprocess.Popen | None = None

    def url(self, password: str | None = None) -> str:
        """The URL with this server's password, or with ``password`` ("" for none)."""
        password = self.password if password is None else password
        return f"redis://{f':{password}@' if password else ''}127.0.0.1:{self.port}/0"

    def start(self) -> None:
        args = ["redis-server", "--port", str(self.port), "--bind", "127.0.0.1", "--save", "", "--appendonly", "no"]
        args += ["--dir", str(self.folder)] + (["--requirepass", self.password] if self.password else [])
        log = open(self.folder / f"redis-{self.port}.log", "ab")  # noqa: SIM115  (the child holds it)
        self.process = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT)
        import redis

        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            try:
                redis.Redis.from_url(self.url(), socket_connect_timeout=1).ping()
                return
            except redis.RedisError:
                time.sleep(0.05)
        raise AssertionError(f"redis-server on port {self.port} did not answer within 20 s")

    def stop(self) -> None:
        """SIGKILL: nothing is saved, as a crashed or recreated Redis container without persistence."""
        if self.process is not None:
            self.process.kill()
            self.process.wait(timeout=30)
            self.process = None


@pytest.fixture
def private_redis(tmp_path: Path):
    """A password-protected redis-server of this test only (see :class:`RedisServer`)."""
    if shutil.which("redis-server") is None:
        unavailable("redis-server is not installed (scripts/setup.sh installs Debian's redis-server)")
    server = RedisServer(tmp_path, password=f"pw-{uuid.uuid4().hex[:12]}")
    server.start()
    yield server
    server.stop()


@pytest.fixture(scope="module")
def browser():
    """Headless Chromium (Playwright), one per test module."""
    from ui_helpers import CHROMIUM, launch

    if not CHROMIUM.is_file():
        unavailable(
            f"browser tests need Chromium at {CHROMIUM} (scripts/setup.sh installs Debian's 'chromium'; "
            "CURVEFM_CHROMIUM points elsewhere)"
        )
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = launch(playwright)
        yield browser
        browser.close()
