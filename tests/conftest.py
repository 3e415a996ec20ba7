"""Fixtures shared by the test suite."""

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def shared_data_path() -> Path:
    return Path(os.environ.get("CURVEFM_SHARED_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The real meshes with ground truth (../shared/data or $CURVEFM_SHARED_DATA)."""
    path = shared_data_path()
    if not path.is_dir():
        pytest.skip(f"shared data folder {path} is absent (set CURVEFM_SHARED_DATA)")
    return path
