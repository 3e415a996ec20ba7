"""Backups: SQLite's online backup and restore; PostgreSQL points at pg_dump."""

from __future__ import annotations

import pytest
from support.records import fresh_database

from curvefm.errors import InvalidInput, NotFound
from curvefm.records import open_database
from curvefm.records.backup import backup, restore
from curvefm.records.users import Users


def test_sqlite_backup_and_restore(tmp_path):
    database = open_database(tmp_path / "data")
    users = Users(database)
    token = users.add("alice")
    saved = backup(database, tmp_path / "backup.db")
    assert saved.is_file() and not (tmp_path / "backup.db-wal").exists()
    with pytest.raises(InvalidInput):
        backup(database, saved)  # never over an existing file
    users.remove("alice")
    users.add("bob")
    restore(database, saved)
    assert [u.name for u in Users(database).list()] == ["alice"]
    assert Users(database).authenticate(token).name == "alice"
    with pytest.raises(NotFound):
        restore(database, tmp_path / "missing.db")
    (tmp_path / "junk.db").write_bytes(b"not a database" * 100)
    with pytest.raises(Exception):  # noqa: B017 (sqlite3 says "file is not a database")
        restore(database, tmp_path / "junk.db")
    assert [u.name for u in Users(database).list()] == ["alice"]
    database.dispose()


def test_postgresql_names_pg_dump(tmp_path):
    with fresh_database("postgresql", tmp_path) as url:
        database = open_database(url=url)
        with pytest.raises(InvalidInput, match="pg_dump"):
            backup(database, tmp_path / "x.db")
        database.dispose()
