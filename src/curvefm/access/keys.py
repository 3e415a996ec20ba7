"""The secret that signs login cookies: ``<data>/access/signing.key``, random bytes made on first use, readable
by its owner only. Every API process of a data directory reads the same key, so a cookie one of them made is
good at all of them; deleting the file logs everyone out (a new key is made on next start)."""

from __future__ import annotations

import os
import secrets
import tempfile
from pathlib import Path

from curvefm.access.common import access_dir
from curvefm.errors import InternalError

KEY_BYTES = 32


def signing_key(data_dir: str | os.PathLike[str] | None = None) -> bytes:
    path = access_dir(data_dir) / "signing.key"
    try:
        key = path.read_bytes()
    except FileNotFoundError:
        key = _create(path)
    if len(key) != KEY_BYTES:
        raise InternalError("the signing key <data>/access/signing.key is damaged; delete it (everyone logs in again)")
    return key


def _create(path: Path) -> bytes:
    """Write a new key beside ``path`` (mkstemp makes it 0600), then link it into place: linking fails when
    another process was first, and then its key is the one."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".signing.key.")
    key = secrets.token_bytes(KEY_BYTES)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(key)
            f.flush()
            os.fsync(f.fileno())
        try:
            os.link(tmp, path)
        except FileExistsError:
            return path.read_bytes()
        return key
    finally:
        os.unlink(tmp)
