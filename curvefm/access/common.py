"""What the user store and the audit log share: their folder and their clock."""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

from curvefm.store import default_data_dir


def access_dir(data_dir: str | os.PathLike | None) -> Path:
    """``<data>/access``, created readable by its owner only (it holds token hashes and the audit log)."""
    folder = Path(data_dir if data_dir is not None else default_data_dir()) / "access"
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    return folder


def timestamp(moment: datetime | None = None) -> str:
    """UTC ISO 8601 with milliseconds and a ``Z``: one fixed width, so timestamps sort as strings."""
    moment = (moment or datetime.now(UTC)).astimezone(UTC)
    return moment.isoformat(timespec="milliseconds").replace("+00:00", "Z")


@contextlib.contextmanager
def locked(lock_path: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``lock_path`` (made if absent): one holder at a time, across processes."""
    fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # closing releases the lock
