"""A test that lacks what it needs skips on a developer's machine and fails under CI, saying what is missing."""

import os
from typing import NoReturn

import pytest


def in_ci() -> bool:
    return os.environ.get("CI", "").lower() not in ("", "0", "false")


def unavailable(reason: str) -> NoReturn:
    """End a test that lacks something it needs (the shared data, Redis, Chromium, a program): a skip on a
    developer's machine, a failure with the reason under CI (``CI`` set), where nothing may be missing."""
    if in_ci():
        pytest.fail(f"{reason} [CI is set: a missing requirement fails the test]", pytrace=False)
    pytest.skip(reason)
