"""The engine: where the database is, and SQLite's settings."""

from __future__ import annotations

import pytest

from curvefm.errors import InvalidInput
from curvefm.records import Database, database_url, open_database
from curvefm.records.engine import DATABASE_FILE


def test_the_url_comes_from_the_environment_else_the_data_directory(tmp_path, monkeypatch):
    monkeypatch.delenv("CURVEFM_DATABASE_URL", raising=False)
    assert database_url(tmp_path) == f"sqlite:///{tmp_path / DATABASE_FILE}"
    monkeypatch.setenv("CURVEFM_DATABASE_URL", "postgresql+psycopg://lab@db/curvefm")
    assert database_url(tmp_path) == "postgresql+psycopg://lab@db/curvefm"
    assert database_url(tmp_path, url="sqlite:///x.db") == "sqlite:///x.db"


def test_sqlite_settings(tmp_path, monkeypatch):
    monkeypatch.delenv("CURVEFM_DATABASE_URL", raising=False)
    monkeypatch.delenv("CURVEFM_SQLITE_SYNCHRONOUS", raising=False)
    database = open_database(tmp_path / "new")  # the folder is made
    assert (tmp_path / "new" / DATABASE_FILE).is_file()
    with database.read() as conn:
        pragma = {name: conn.exec_driver_sql(f"PRAGMA {name}").scalar() for name in ("journal_mode", "foreign_keys")}
        assert pragma == {"journal_mode": "wal", "foreign_keys": 1}
        assert conn.exec_driver_sql("PRAGMA synchronous").scalar() == 2  # FULL
        assert conn.exec_driver_sql("PRAGMA busy_timeout").scalar() == 30_000
    database.dispose()
    monkeypatch.setenv("CURVEFM_SQLITE_SYNCHRONOUS", "sometimes")
    with pytest.raises(InvalidInput):
        Database(f"sqlite:///{tmp_path / 'other.db'}")
