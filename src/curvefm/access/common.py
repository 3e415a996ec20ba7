"""The access folder ``<data>/access`` (the login-cookie key)."""

from __future__ import annotations

import os
from pathlib import Path

from curvefm.store import default_data_dir


def access_dir(data_dir: str | os.PathLike[str] | None) -> Path:
    """``<data>/access``, created readable by its owner only (it holds the login-cookie key)."""
    folder = Path(data_dir if data_dir is not None else default_data_dir()) / "access"
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    return folder
