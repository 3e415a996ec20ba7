"""Per-user quotas: stored bytes (413), sessions and concurrent jobs (429), each error naming its setting.

What a user is charged for is kept by :class:`curvefm.access.Usage`; sizes and states are measured when a quota
is checked. Admins are exempt (what they make is still recorded). A check and the change it admits hold the
user's lock, so a user's parallel requests cannot pass one check together and overshoot a count; a result is
measured only once its job wrote it, so a refinement may take a user past the byte quota, which then refuses
the next upload or refinement.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Literal

from curvefm.access import Usage, User
from curvefm.errors import NotFound, ResourceLimit, TooMany
from curvefm.geometry import Mesh
from curvefm.service.settings import Settings, env_name
from curvefm.session import SessionStore
from curvefm.store import Store
from curvefm.workers.interface import ENDED_STATES, JobQueue

Charged = Literal["shapes", "sessions", "jobs"]
Charge = Callable[[str], None]
"""Records the id of what an admitted request made (a shape, session or job) against the user's quotas."""


class Quotas:
    def __init__(self, settings: Settings, usage: Usage, store: Store, records: SessionStore, queue: JobQueue):
        self.settings, self.usage, self.store, self.records, self.queue = settings, usage, store, records, queue

    @contextlib.contextmanager
    def admit(self, user: User | None, kind: Charged, incoming_bytes: int = 0) -> Iterator[Charge]:
        """Hold the user's usage while the block makes one thing of ``kind``, after checking its quotas:

        * ``shapes``: 413 when ``incoming_bytes`` (the new mesh, :func:`stored_bytes`) pass the byte quota;
        * ``sessions``: 429 at the sessions quota;
        * ``jobs``: 429 at the concurrent-jobs quota, 413 when the user's bytes are at their quota already (the
          job's results would add more).

        The block calls the yielded function with the id of what it made. Without a user (the demo, made by
        the server), nothing is checked or charged."""
        if user is None:
            yield lambda made: None
            return
        with self.usage.edit(user.name) as ids:
            self._forget_gone(ids)
            if not user.admin:
                if kind == "shapes":
                    self._check_bytes(ids, incoming_bytes)
                else:
                    self._check_count(user, ids, kind)
                if kind == "jobs":
                    self._check_bytes(ids, 0)
            yield lambda made: ids[kind].append(made) if made not in ids[kind] else None

    def used_bytes(self, ids: dict[str, list[str]]) -> int:
        meshes = sum(_size(self.store.mesh_path(mesh_id)) for mesh_id in ids["shapes"])
        return meshes + sum(_folder_size(self._results(job_id)) for job_id in ids["results"])

    # -- helpers ------------------------------------------------------------------------------------------
    def _check_count(self, user: User, ids: dict[str, list[str]], kind: str) -> None:
        setting, what, remedy = COUNTS[kind]
        limit, count = getattr(self.settings, setting), len(ids[kind])
        if limit and count >= limit:
            raise TooMany(
                f"{user.name} has {count} {what}, the most allowed ({env_name(setting)}={limit}); {remedy}",
                setting=env_name(setting),
            )

    def _check_bytes(self, ids: dict[str, list[str]], incoming: int) -> None:
        limit, used = self.settings.quota_bytes, self.used_bytes(ids)
        if limit and (used + incoming > limit or used >= limit):
            adds = f", this would add {incoming}" if incoming else ""
            raise ResourceLimit(
                f"your stored data is {used} bytes{adds}, and the quota is {limit} bytes ({env_name('quota_bytes')})"
                "; results expire after a while, or delete results and shapes you uploaded, or ask an admin to "
                "raise the limit",
                setting=env_name("quota_bytes"),
            )

    def _forget_gone(self, ids: dict[str, list[str]]) -> None:
        """Drop what no longer exists; move ended jobs to ``results`` (where their result folders are)."""
        ids["shapes"] = [mesh_id for mesh_id in ids["shapes"] if self.store.has_mesh(mesh_id)]
        ids["sessions"] = [session_id for session_id in ids["sessions"] if self.records.exists(session_id)]
        active = [job_id for job_id in ids["jobs"] if self._is_active(job_id)]
        ended = [job_id for job_id in ids["jobs"] if job_id not in active]
        ids["jobs"] = active
        ids["results"] = [job_id for job_id in ids["results"] + ended if self._results(job_id).is_dir()]

    def _is_active(self, job_id: str) -> bool:
        try:
            return self.queue.get(job_id).state not in ENDED_STATES
        except NotFound:
            return False

    def _results(self, job_id: str) -> Path:
        return self.store.root / "results" / job_id


COUNTS = {
    "sessions": ("quota_sessions", "sessions", "delete one first or ask an admin to raise the limit"),
    "jobs": ("quota_jobs", "jobs queued or running", "wait for one to end or cancel one"),
}
"""Counted kind -> (setting, what is counted, what to do)."""


def stored_bytes(mesh: Mesh) -> int:
    """About what :meth:`curvefm.store.Store.put_mesh` writes for ``mesh`` (its arrays, uncompressed)."""
    arrays = (mesh.vertices, mesh.faces, mesh.file_ids, mesh.uv)
    return sum(array.nbytes for array in arrays if array is not None)


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except FileNotFoundError:
        return 0


def _folder_size(folder: Path) -> int:
    try:
        return sum(_size(path) for path in folder.iterdir())
    except FileNotFoundError:  # expired, or never written
        return 0
