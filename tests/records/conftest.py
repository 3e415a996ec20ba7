"""Fixtures of the records' tests: a fresh database per test, on SQLite and on PostgreSQL (skipped where no server
answers at ``CURVEFM_TEST_POSTGRES``, default ``postgresql://postgres@127.0.0.1:5432/test``)."""

from __future__ import annotations

import secrets

import pytest
from support.records import MigratedTemplates, fresh_database


@pytest.fixture(params=["sqlite", "postgresql"])
def engine_kind(request) -> str:
    return request.param


@pytest.fixture
def db_url(engine_kind, tmp_path):
    """A new, empty database."""
    with fresh_database(engine_kind, tmp_path) as url:
        yield url


@pytest.fixture(scope="session")
def migrated_templates(tmp_path_factory):
    templates = MigratedTemplates(tmp_path_factory.mktemp("templates"))
    yield templates
    templates.drop_all()


@pytest.fixture
def migrated_url(engine_kind, tmp_path, migrated_templates):
    """A new database at the newest schema, with no rows (a copy of the session's migrated template)."""
    with migrated_templates.copy(engine_kind, tmp_path) as url:
        yield url


@pytest.fixture
def db(migrated_url):
    from curvefm.records import open_database

    database = open_database(url=migrated_url)
    yield database
    database.dispose()


@pytest.fixture
def token() -> str:
    return secrets.token_hex(4)
