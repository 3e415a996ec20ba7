"""What each user's quotas are charged for: ``<data>/access/usage/<user>.json``.

One file per user, the ids of what they made, by kind::

    {"shapes": ["<mesh hash>", ...], "sessions": ["<session id>", ...],
     "jobs": ["<job id>", ...], "results": ["<job id>", ...]}

``jobs`` are jobs that may still be queued or running; ``results`` are ended jobs whose result folder may
exist. Sizes are not stored: whoever checks a quota measures what is on disk and drops the ids of what is
gone (deleted, or expired), so the ledger cannot drift from the data. A shape is charged to its first
uploader only (it is stored once, content-addressed).

Each change holds the user's lock across processes, so a check and the change that follows it (see
:meth:`Usage.edit`) are one step for that user.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator
from pathlib import Path

from curvefm.access.common import access_dir, locked
from curvefm.store import atomic_write

KINDS = ("shapes", "sessions", "jobs", "results")


class Usage:
    def __init__(self, data_dir: str | os.PathLike | None = None):
        self.folder = access_dir(data_dir) / "usage"
        self.folder.mkdir(mode=0o700, exist_ok=True)

    def read(self, user: str) -> dict[str, list[str]]:
        """The user's ids by kind (empty lists for a user with none)."""
        try:
            stored = json.loads(self._path(user).read_bytes())
        except FileNotFoundError:
            stored = {}
        return {kind: list(stored.get(kind, [])) for kind in KINDS}

    @contextlib.contextmanager
    def edit(self, user: str) -> Iterator[dict[str, list[str]]]:
        """Hold the user's lock; yield their ids to change in place; store them if they changed (not when the
        block raised)."""
        with locked(self.folder / f".{user}.lock"):
            before = self.read(user)
            ids = {kind: list(items) for kind, items in before.items()}
            yield ids
            if ids != before:
                atomic_write(self._path(user), json.dumps(ids).encode())

    def _path(self, user: str) -> Path:
        return self.folder / f"{user}.json"  # user names are checked by UserStore: no '/', never '.' or '..'
