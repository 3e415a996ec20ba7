"""The database of a data directory: its URL, the engine and the two kinds of transaction.

``CURVEFM_DATABASE_URL`` (``postgresql+psycopg://user@host/db``) names a lab's PostgreSQL; without it the records
live in SQLite at ``<data>/curvefm.db``, in WAL mode (readers never wait for the writer), with foreign keys on
and ``busy_timeout`` so a writer waits for another instead of failing.

:meth:`Database.write` is a transaction that takes the write lock when it begins (SQLite: ``BEGIN IMMEDIATE``),
so what it reads (a revision, a count against a quota) cannot change before it commits; on PostgreSQL the
repositories lock the rows they check (``SELECT ... FOR UPDATE``) or make the check part of the ``UPDATE``.
:meth:`Database.read` is a plain transaction: one consistent snapshot, no lock.
"""

from __future__ import annotations

import contextlib
import os
import sqlite3
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, cast

from sqlalchemy import Connection, Engine, create_engine, event
from sqlalchemy.engine import make_url
from sqlalchemy.exc import DBAPIError, OperationalError

from curvefm.errors import DiskFull, InvalidInput, Unavailable, disk_full_error
from curvefm.store import default_data_dir

DATABASE_FILE = "curvefm.db"
URL_VARIABLE = "CURVEFM_DATABASE_URL"
BUSY_TIMEOUT_MS = 30_000
"""How long a SQLite writer waits for another writer before failing (as the old record lock's 30 s);
``CURVEFM_SQLITE_BUSY_TIMEOUT`` (milliseconds) changes it. The service answers such a failure 503."""
BUSY_TIMEOUT_VARIABLE = "CURVEFM_SQLITE_BUSY_TIMEOUT"
SQLITE_SYNCHRONOUS = "FULL"  # chosen in docs/decisions.md#commit-durability
"""Each commit is on disk when it returns (as the old stores' fsync'ed files). ``CURVEFM_SQLITE_SYNCHRONOUS=NORMAL``
skips the fsync of each commit (one per checkpoint instead): still never corrupt and safe against a crashed
process, but a power cut may lose the last commits; it halves a curve edit's write where fsync is slow."""
SYNCHRONOUS_VARIABLE = "CURVEFM_SQLITE_SYNCHRONOUS"


def database_url(data_dir: str | os.PathLike[str] | None = None, url: str | None = None) -> str:
    """``url``, else ``$CURVEFM_DATABASE_URL``, else the SQLite file of the data directory."""
    chosen = url or os.environ.get(URL_VARIABLE)
    if chosen:
        return chosen
    folder = Path(data_dir) if data_dir is not None else default_data_dir()
    return f"sqlite:///{(folder / DATABASE_FILE).absolute()}"


class Database:
    """An engine with the connection settings of its kind, shared by every repository of one process."""

    def __init__(self, url: str, echo: bool = False):
        self.url = make_url(url)
        self.is_sqlite = self.url.get_backend_name() == "sqlite"
        # SQLite has one writer at a time, and a thread that finds it busy sleeps in growing steps (up to 100 ms)
        # however soon the writer ends: this process's writers wait their turn here instead, handed on at once.
        self._writers = threading.RLock() if self.is_sqlite else contextlib.nullcontext()
        if self.is_sqlite:
            path = self.url.database
            if path and path != ":memory:":
                Path(path).parent.mkdir(parents=True, exist_ok=True)
            busy_ms = busy_timeout_ms()
            self.engine = create_engine(
                self.url, echo=echo, connect_args={"timeout": busy_ms / 1000}, pool_size=8, max_overflow=16
            )
            _sqlite_settings(self.engine)
        else:
            self.engine = create_engine(
                self.url, echo=echo, pool_size=8, max_overflow=16, pool_pre_ping=True, pool_recycle=1800
            )

    @contextmanager
    def read(self) -> Iterator[Connection]:
        """A read-only transaction on one snapshot: a record read in several statements (a session's row, then its
        curves) is of one commit. (SQLite's transactions are snapshots; PostgreSQL's default, READ COMMITTED,
        takes a new snapshot per statement, so reads ask for REPEATABLE READ.)"""
        with self.engine.connect() as conn:
            if not self.is_sqlite:
                conn = conn.execution_options(isolation_level="REPEATABLE READ")
            with conn.begin():
                yield conn

    @contextmanager
    def write(self) -> Iterator[Connection]:
        """A transaction that commits when the block ends (rolls back when it raises)."""
        with self._writers, self.engine.connect() as conn:
            if self.is_sqlite:
                conn = conn.execution_options(sqlite_immediate=True)
            with conn.begin():
                yield conn

    @contextmanager
    def joined(self, conn: Connection | None) -> Iterator[Connection]:
        """``conn`` when a caller's transaction is given (the work becomes part of it), else a new write."""
        if conn is not None:
            yield conn
            return
        with self.write() as fresh:
            yield fresh

    def check(self) -> str:
        """The database's kind (``sqlite``, ``postgresql``) once it answers a query; :class:`Unavailable` naming
        it when it does not, :class:`DiskFull` when its disk is full."""
        try:
            with self.engine.connect() as conn:
                conn.exec_driver_sql("SELECT 1")
        except OperationalError as exc:
            raise self.failure(exc) from None
        return self.url.get_backend_name()

    def failure(self, exc: OperationalError, located: bool = False) -> DiskFull | Unavailable:
        """What the database's failure to answer means: its disk is full, or it does not answer (naming its kind;
        ``located``: its URL too, without the password, for the operator at a command line: never in an answer,
        where a SQLite URL would show a path)."""
        where = self.shown if located else f"({self.url.get_backend_name()})"
        return disk_full_error(exc) or Unavailable(f"the records' database {where} does not answer: {_reason(exc)}")

    @property
    def shown(self) -> str:
        """The URL without its password."""
        return self.url.render_as_string(hide_password=True)

    def dispose(self) -> None:
        self.engine.dispose()

    def __repr__(self) -> str:
        return f"Database({self.url.render_as_string(hide_password=True)!r})"


def busy_timeout_ms() -> int:
    text = os.environ.get(BUSY_TIMEOUT_VARIABLE, "")
    if not text:
        return BUSY_TIMEOUT_MS
    if not text.isdigit():
        raise InvalidInput(f"{BUSY_TIMEOUT_VARIABLE} is a whole number of milliseconds, got {text!r}")
    return int(text)


def _reason(exc: OperationalError) -> str:
    return " ".join(str(exc.orig).split())[:200]


def _sqlite_settings(engine: Engine) -> None:
    synchronous = os.environ.get(SYNCHRONOUS_VARIABLE, SQLITE_SYNCHRONOUS).upper()
    if synchronous not in ("FULL", "NORMAL", "EXTRA"):
        raise InvalidInput(f"{SYNCHRONOUS_VARIABLE} is FULL, NORMAL or EXTRA, got {synchronous!r}")

    @event.listens_for(engine, "connect")
    def connect(dbapi_connection: Any, _record: Any) -> None:
        dbapi_connection.isolation_level = None  # we emit BEGIN ourselves (pysqlite's own is deferred and late)
        cursor = dbapi_connection.cursor()
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.execute(f"PRAGMA busy_timeout={busy_timeout_ms()}")
        cursor.execute(f"PRAGMA synchronous={synchronous}")
        cursor.close()

    @event.listens_for(engine, "begin")
    def begin(conn: Connection) -> None:
        statement = "BEGIN IMMEDIATE" if conn.get_execution_options().get("sqlite_immediate", False) else "BEGIN"
        # on the driver's connection: through SQLAlchemy's execution machinery a BEGIN cost more than most queries
        try:
            cast(sqlite3.Connection, conn.connection.driver_connection).execute(statement)
        except sqlite3.Error as exc:
            raise DBAPIError.instance(statement, None, exc, sqlite3.Error) from exc


_shared: dict[str, Database] = {}
_shared_lock = threading.Lock()


def shared_database(data_dir: str | os.PathLike[str] | None = None, url: str | None = None) -> Database:
    """One migrated :class:`Database` per URL in this process (a worker finds its job's records by the job's
    ``data_dir``; opening an engine, and checking the schema, for each job would cost more than the job's writes)."""
    resolved = database_url(data_dir, url)
    with _shared_lock:
        database = _shared.get(resolved)
        if database is None:
            database = _shared[resolved] = open_database(url=resolved)
        return database


def open_database(
    data_dir: str | os.PathLike[str] | None = None, url: str | None = None, upgrade: bool = True
) -> Database:
    """The data directory's database, migrated to the newest schema when ``upgrade``."""
    database = Database(database_url(data_dir, url))
    if upgrade:
        from curvefm.records.migrate import upgrade as run_upgrade

        run_upgrade(database)
    return database
