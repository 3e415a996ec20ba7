"""Fixtures of the records' tests: a fresh database per test, on SQLite and on PostgreSQL (skipped where no server
answers at ``CURVEFM_TEST_POSTGRES``, default ``postgresql://postgres@127.0.0.1:5432/test``)."""

from __future__ import annotations

import secrets

import pytest
from support.records import fresh_database


@pytest.fixture(params=["sqlite", "postgresql"])
def engine_kind(request) -> str:
    return request.param


@pytest.fixture
def db_url(engine_kind, tmp_path):
    with fresh_database(engine_kind, tmp_path) as url:
        yield url


@pytest.fixture
def db(db_url):
    from curvefm.records import open_database

    database = open_database(url=db_url)
    yield database
    database.dispose()


@pytest.fixture
def token() -> str:
    return secrets.token_hex(4)
