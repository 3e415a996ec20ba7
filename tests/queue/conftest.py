"""Fixtures of the queue tests."""

import shutil
import uuid
from pathlib import Path

import pytest
from support.ci import unavailable
from support.redis_servers import RedisServer


@pytest.fixture
def private_redis(tmp_path: Path):
    """A password-protected redis-server of this test only (see :class:`support.redis_servers.RedisServer`)."""
    if shutil.which("redis-server") is None:
        unavailable("redis-server is not installed (scripts/setup.sh installs Debian's redis-server)")
    server = RedisServer(tmp_path, password=f"pw-{uuid.uuid4().hex[:12]}")
    server.start()
    yield server
    server.stop()
