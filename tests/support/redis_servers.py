"""Redis for the tests: the shared Redis every queue test uses (each test under a key prefix of its own, removed
afterwards), and a private ``redis-server`` of one test that can be stopped and restarted empty."""

import os
import subprocess
import time
from pathlib import Path

from support.processes import free_port

REDIS_URL = os.environ.get("CURVEFM_TEST_REDIS_URL", "redis://127.0.0.1:6379/0")


def delete_prefix(redis_url: str, prefix: str) -> None:
    """Delete every Redis key of a test's queue-name prefix (queues, registries, jobs, workers, our own keys), and
    nothing else."""
    import redis

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
