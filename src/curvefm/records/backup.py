"""Backups of the records.

SQLite: :func:`backup` copies the live database with SQLite's online backup API (a consistent snapshot while the
service keeps running: writers wait a moment, readers not at all) to a single file; :func:`restore` copies such
a file back over the database (stop the service and the workers first: they would keep reading their open
snapshot).

PostgreSQL: use the server's tools, which know its roles and permissions::

    pg_dump --format=custom --file=curvefm.dump "$DATABASE"       # backup
    pg_restore --clean --if-exists --dbname="$DATABASE" curvefm.dump   # restore

(``$DATABASE``: ``CURVEFM_DATABASE_URL`` without the ``+psycopg``.) The blobs (``meshes/``, ``bases/``,
``displays/``, ``results/``) are files: copy the data directory beside the database backup.
"""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

from curvefm.errors import InvalidInput, NotFound
from curvefm.records.engine import Database

PG_DUMP_HINT = (
    "the records are in PostgreSQL: back up with pg_dump --format=custom --file=FILE DATABASE and restore with "
    "pg_restore --clean --if-exists --dbname=DATABASE FILE"
)


def backup(database: Database, target: str | os.PathLike[str]) -> Path:
    """Copy the SQLite database to ``target`` (a new file); returns its path."""
    source = _sqlite_path(database)
    target = Path(target)
    if target.exists():
        raise InvalidInput(f"{target} exists; name a new file for the backup")
    target.parent.mkdir(parents=True, exist_ok=True)
    live, copy = sqlite3.connect(source), sqlite3.connect(target)
    try:
        live.backup(copy)
        copy.execute("PRAGMA journal_mode=DELETE")  # one self-contained file, no -wal beside it
    finally:
        copy.close()
        live.close()
    return target


def restore(database: Database, source: str | os.PathLike[str]) -> None:
    """Replace the SQLite database's content by the backup ``source`` (made by :func:`backup`)."""
    target = _sqlite_path(database)
    source = Path(source)
    if not source.is_file():
        raise NotFound(f"no backup file {source}")
    saved = sqlite3.connect(f"file:{source}?mode=ro", uri=True)
    try:
        check = saved.execute("PRAGMA integrity_check").fetchone()[0]
        if check != "ok":
            raise InvalidInput(f"{source} is not a sound SQLite database ({check})")
        database.dispose()
        live = sqlite3.connect(target)
        try:
            saved.backup(live)
            live.execute("PRAGMA journal_mode=WAL")
        finally:
            live.close()
    finally:
        saved.close()


def _sqlite_path(database: Database) -> str:
    if not database.is_sqlite:
        raise InvalidInput(PG_DUMP_HINT)
    path = database.url.database
    if not path or path == ":memory:":
        raise InvalidInput("an in-memory database has nothing to back up")
    return path
