"""Paths the tests compute: the checkout, the shared data with ground truth, where test artifacts go."""

import os
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]
REPO = TESTS.parent
ARTIFACTS = REPO / "test-artifacts"
"""Screenshots and other files a test leaves for a person to look at (ignored by git)."""


def shared_data_path() -> Path:
    """The real meshes with ground truth: ``$CURVEFM_SHARED_DATA``, else ``../shared/data`` beside the checkout."""
    return Path(os.environ.get("CURVEFM_SHARED_DATA", REPO.parent / "shared" / "data"))
