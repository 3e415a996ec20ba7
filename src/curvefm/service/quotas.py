"""Per-user quotas: stored bytes (413), sessions and concurrent jobs (429), each error naming its setting.

The counting is :class:`curvefm.records.usage.Quotas`': queries over what the database records (the shapes a user
was charged for and their jobs' result bytes, the sessions they own, collections' member sessions included, their
queued or running jobs), made in the write transaction that then stores the new shape or session, so a user's
parallel requests cannot pass one check together, and a refused request stores nothing. Admins are exempt (what
they make is still theirs). A result is measured once its job wrote it, so a refinement may take a user past the
byte quota, which then refuses the next upload or refinement.
"""

from __future__ import annotations

from curvefm.geometry import Mesh
from curvefm.records import Database
from curvefm.records.usage import Limits, Quotas
from curvefm.service.settings import Settings, env_name


def quotas(settings: Settings, database: Database) -> Quotas:
    """The quotas of ``settings`` (0: no limit), checked in ``database``."""
    limits = Limits(
        bytes=settings.quota_bytes,
        sessions=settings.quota_sessions,
        jobs=settings.quota_jobs,
        bytes_setting=env_name("quota_bytes"),
        sessions_setting=env_name("quota_sessions"),
        jobs_setting=env_name("quota_jobs"),
    )
    return Quotas(database, limits)


def stored_bytes(mesh: Mesh) -> int:
    """About what :meth:`curvefm.store.Store.put_mesh` writes for ``mesh`` (its arrays, uncompressed)."""
    arrays = (mesh.vertices, mesh.faces, mesh.file_ids, mesh.uv)
    return sum(array.nbytes for array in arrays if array is not None)
