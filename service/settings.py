"""Service settings, from the environment with explicit overrides (what ``curvefm serve`` options set)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field, fields
from pathlib import Path

from curvefm.session import SessionLimits
from curvefm.store import default_data_dir

DEFAULT_MAX_UPLOAD_BYTES = 200 * 1024 * 1024
DEFAULT_MAX_BODY_BYTES = 4 * 1024 * 1024
SESSION_LIMITS = tuple(f.name for f in fields(SessionLimits))
LIMITS = ("max_upload_bytes", "max_body_bytes", *SESSION_LIMITS)
"""The limits: each a positive integer, read from ``CURVEFM_<NAME>`` (``CURVEFM_MAX_K``) and named in its error."""


@dataclass(frozen=True)
class Settings:
    data_dir: Path = field(default_factory=default_data_dir)
    redis_url: str | None = None
    """``None``: jobs run in an in-process executor."""
    max_upload_bytes: int = DEFAULT_MAX_UPLOAD_BYTES
    """The largest shape upload (``POST /shapes``), counted as the body arrives (chunked too)."""
    max_body_bytes: int = DEFAULT_MAX_BODY_BYTES
    """The largest body of any other request."""
    session_limits: SessionLimits = field(default_factory=SessionLimits)
    queue_prefix: str = ""
    job_retries: int = 1
    """How often a job whose worker died is run again before it is marked failed (RQ mode)."""
    embedded_workers: int = 2
    demo: bool = False

    @classmethod
    def from_env(cls, **overrides) -> Settings:
        """``CURVEFM_DATA``, ``CURVEFM_REDIS_URL``, ``CURVEFM_QUEUE_PREFIX``, ``CURVEFM_JOB_RETRIES`` and a
        ``CURVEFM_<NAME>`` for each of :data:`LIMITS`; overrides (settings or limits by name) that are ``None``
        are ignored."""
        env = os.environ
        values = {
            "data_dir": default_data_dir(),
            "redis_url": env.get("CURVEFM_REDIS_URL") or None,
            "queue_prefix": env.get("CURVEFM_QUEUE_PREFIX", ""),
            "job_retries": int(env.get("CURVEFM_JOB_RETRIES", 1)),
        }
        values.update({name: env[f"CURVEFM_{name.upper()}"] for name in LIMITS if f"CURVEFM_{name.upper()}" in env})
        unknown = set(overrides) - {f.name for f in fields(cls)} - set(LIMITS)
        if unknown:
            raise TypeError(f"unknown settings: {', '.join(sorted(unknown))}")
        values.update({key: value for key, value in overrides.items() if value is not None})
        for name in set(LIMITS) & set(values):
            values[name] = _positive(name, values[name])
        session_limits = {name: values.pop(name) for name in SESSION_LIMITS if name in values}
        values["session_limits"] = SessionLimits(**session_limits)
        values["data_dir"] = Path(values["data_dir"]).expanduser()
        return cls(**values)


def _positive(name: str, value: int | str) -> int:
    try:
        number = int(value)
    except ValueError:
        number = 0
    if number < 1:
        raise ValueError(f"{name} (CURVEFM_{name.upper()}) must be a positive integer, got {value!r}")
    return number
