"""Service settings, from the environment with explicit overrides (what ``curvefm serve`` options set)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field, fields
from pathlib import Path

from curvefm.store import default_data_dir

DEFAULT_MAX_UPLOAD_BYTES = 200 * 1024 * 1024


@dataclass(frozen=True)
class Settings:
    data_dir: Path = field(default_factory=default_data_dir)
    redis_url: str | None = None
    """``None``: jobs run in an in-process executor."""
    max_upload_bytes: int = DEFAULT_MAX_UPLOAD_BYTES
    queue_prefix: str = ""
    job_retries: int = 1
    """How often a job whose worker died is run again before it is marked failed (RQ mode)."""
    embedded_workers: int = 2
    demo: bool = False

    @classmethod
    def from_env(cls, **overrides) -> Settings:
        """``CURVEFM_DATA``, ``CURVEFM_REDIS_URL``, ``CURVEFM_MAX_UPLOAD_BYTES``, ``CURVEFM_QUEUE_PREFIX``,
        ``CURVEFM_JOB_RETRIES``; overrides that are ``None`` are ignored."""
        env = os.environ
        values = {
            "data_dir": default_data_dir(),
            "redis_url": env.get("CURVEFM_REDIS_URL") or None,
            "max_upload_bytes": int(env.get("CURVEFM_MAX_UPLOAD_BYTES", DEFAULT_MAX_UPLOAD_BYTES)),
            "queue_prefix": env.get("CURVEFM_QUEUE_PREFIX", ""),
            "job_retries": int(env.get("CURVEFM_JOB_RETRIES", 1)),
        }
        known = {f.name for f in fields(cls)}
        unknown = set(overrides) - known
        if unknown:
            raise TypeError(f"unknown settings: {', '.join(sorted(unknown))}")
        values.update({key: value for key, value in overrides.items() if value is not None})
        values["data_dir"] = Path(values["data_dir"]).expanduser()
        return cls(**values)
