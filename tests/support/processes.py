"""Service processes for the tests: real ``python -m curvefm.service`` / ``python -m curvefm.workers`` processes in
their own process groups, an authenticated HTTP client of each API, the users of a data directory, free ports."""

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx

from support import records as test_databases
from support.records import database_env

API_COMMAND = ["python", "-m", "curvefm.service"]
WORKER_COMMAND = ["python", "-m", "curvefm.workers"]


TEST_USER = "tester"
"""The user every API fixture's client acts as (not an admin): made on the server's data directory before it starts."""


def bearer(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


def add_user(data_dir: Path, name: str, admin: bool = False) -> str:
    """Make a user on a data directory (the server sees it at once); a user of an earlier server on it gets a new
    token. Returns the token."""
    from curvefm.access import users_of
    from curvefm.errors import Conflict

    users = users_of(data_dir)
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
        self.deployments: dict[tuple[str, str], Path] = {}  # (Redis URL, queue prefix) -> the APIs' data directory

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
        self,
        data_dir: Path,
        redis_url: str | None = None,
        env: dict[str, str] | None = None,
        args=(),
        user=TEST_USER,
        port: int | None = None,
    ) -> Api:
        """An API process on ``data_dir`` and ``port`` (default: a free one), with a client of ``user`` (None: no
        user is made, so the server makes its local admin and prints the login URL)."""
        port = port or free_port()
        args = [*API_COMMAND, "--host", "127.0.0.1", "--port", str(port), "--data", str(data_dir), *args]
        if redis_url:
            args += ["--redis-url", redis_url]
        name = f"api-{port}"
        token = self.token(data_dir, user) if user else None
        if redis_url:
            prefix = (env or {}).get("CURVEFM_QUEUE_PREFIX", os.environ.get("CURVEFM_QUEUE_PREFIX", ""))
            self.deployments[(redis_url, prefix)] = data_dir
        # tests drive a server far faster than a person does: no rate limit unless the test sets one
        process = self.start(args, name, {"CURVEFM_RATE_LIMIT": "0", **database_env(data_dir), **(env or {})})
        api = Api(process, f"http://127.0.0.1:{port}", self.folder / f"{name}.log", data_dir, token)
        wait_until_healthy(api)
        return api

    def token(self, data_dir: Path, user: str) -> str:
        """The token of ``user`` on ``data_dir``: the one given to an earlier API on it while it still works (two
        processes serving one directory share the user), else a new one."""
        from curvefm.access import users_of

        token = self.tokens.get((data_dir, user))
        if token is None or users_of(data_dir).authenticate(token) is None:
            token = add_user(data_dir, user)
        self.tokens[(data_dir, user)] = token
        return token

    def worker(
        self,
        redis_url: str,
        prefix: str,
        name: str,
        data_dir: Path | None = None,
        env: dict[str, str] | None = None,
        queues: list[str] | None = None,
    ) -> subprocess.Popen:
        """A worker of the deployment on ``data_dir``, by default that of the last API started on the same Redis
        and prefix (its records' database: the data directory's, see :func:`support.records.database_env`), with
        ``env`` added to its environment, on ``queues`` (queue names; default: all)."""
        args = [*WORKER_COMMAND, "--redis-url", redis_url, "--name", f"{prefix}{name}"]
        if queues:
            args += ["--queues", *queues]
        data_dir = data_dir or self.deployments.get((redis_url, prefix))
        if data_dir is None and test_databases.current is not None:  # on PostgreSQL: which database?
            raise AssertionError(f"worker {name}: start its API first or pass its data_dir (its records' database)")
        database = database_env(data_dir) if data_dir is not None else {}
        return self.start(args, f"worker-{name}", {**database, "CURVEFM_QUEUE_PREFIX": prefix, **(env or {})})

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
