"""What each engine raises when its disk is full, as the engine raises it, is recognised as :class:`DiskFull` naming
the disk (both engines); other errors are not. SQLite reports SQLITE_FULL at its page limit as on a full disk; the
PostgreSQL server itself raises SQLSTATE 53100 (disk_full) from a statement, as it does when it cannot extend a
file, so what reaches the code is the real psycopg class through SQLAlchemy."""

from __future__ import annotations

import errno

import pytest
from sqlalchemy.exc import DBAPIError, OperationalError

from curvefm.errors import DATA_DISK, DATABASE_DISK, DiskFull, disk_full_error

SQLITE_PAGES = 16
POSTGRES_DISK_FULL = "DO $$ BEGIN RAISE EXCEPTION 'could not extend file' USING ERRCODE = 'disk_full'; END $$"


def engine_disk_full(db) -> DBAPIError:
    """The error the engine raises for a write its disk has no room for."""
    with pytest.raises(OperationalError) as raised, db.write() as conn:
        if db.is_sqlite:
            conn.exec_driver_sql(f"PRAGMA max_page_count = {SQLITE_PAGES}")
            conn.exec_driver_sql("CREATE TABLE filler (data BLOB)")
            conn.exec_driver_sql(f"INSERT INTO filler VALUES (zeroblob({SQLITE_PAGES * 4096}))")
        else:
            conn.exec_driver_sql(POSTGRES_DISK_FULL)
    return raised.value


def test_a_full_disk_of_either_engine_is_disk_full_naming_the_disk(db, engine_kind):
    error = engine_disk_full(db)
    if engine_kind == "sqlite":
        assert error.orig.sqlite_errorname == "SQLITE_FULL"
    else:
        assert type(error.orig) is pytest.importorskip("psycopg").errors.DiskFull
    full = disk_full_error(error)
    assert isinstance(full, DiskFull) and full.code == "disk_full"
    assert full.message.startswith(f"{DATA_DISK if engine_kind == 'sqlite' else DATABASE_DISK} is full")


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EDQUOT])
def test_a_file_write_refused_for_space_is_disk_full_without_its_path(code, tmp_path):
    error = OSError(code, "No space left on device", str(tmp_path / "meshes" / "x.npz"))
    for raised in (error, wrapped(error)):
        full = disk_full_error(raised)
        assert full is not None and full.message.startswith(f"{DATA_DISK} is full")
        assert str(tmp_path) not in full.message


def test_other_errors_are_not_disk_full(db):
    assert disk_full_error(OSError(errno.EACCES, "Permission denied")) is None
    assert disk_full_error(ValueError("no")) is None
    with pytest.raises(DBAPIError) as raised, db.read() as conn:
        conn.exec_driver_sql("SELECT * FROM no_such_table")
    assert disk_full_error(raised.value) is None


def wrapped(error: Exception) -> RuntimeError:
    """``error`` as the cause of another exception, as code that translates errors raises it."""
    try:
        raise RuntimeError("could not store it") from error
    except RuntimeError as outer:
        return outer
