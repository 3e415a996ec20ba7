"""The migrations and the models agree, every revision upgrades and downgrades, and replicas starting together on a
new database migrate it once (both engines)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import inspect, select, text
from support.records import curve, fresh_database, repositories, session_record, shape_id

from curvefm.records import Database, migrate
from curvefm.records import models as m
from curvefm.records.models import Base
from curvefm.records.sessions import stored_bytes

REPLICAS = 4
# A replica's start: say it is ready, wait for the go file (so that every replica is past its imports), then open the
# database as the service does, migrating it.
REPLICA = """
import sys, time
from pathlib import Path
from curvefm.records import open_database
go = Path(sys.argv[2])
Path(sys.argv[3]).touch()
while not go.exists():
    time.sleep(0.005)
open_database(url=sys.argv[1]).dispose()
"""


def _tables(database: Database) -> set[str]:
    with database.engine.connect() as conn:
        return set(inspect(conn).get_table_names()) - {"alembic_version"}


def test_the_migrations_make_what_the_models_describe(db_url):
    database = Database(db_url)
    migrate.upgrade(database)
    with database.engine.connect() as conn:
        context = MigrationContext.configure(conn, opts={"compare_type": True, "compare_server_default": True})
        assert compare_metadata(context, Base.metadata) == []
    assert migrate.current(database) == migrate.head()
    database.dispose()


def test_first_revision_to_last_and_back(db_url):
    database = Database(db_url)
    assert migrate.current(database) is None
    revisions = migrate.revisions()
    assert revisions[-1] == migrate.head()
    for revision in revisions:
        migrate.upgrade(database, revision)
        assert migrate.current(database) == revision
    assert _tables(database) == set(Base.metadata.tables)
    for revision in reversed(revisions[:-1]):
        migrate.downgrade(database, revision)
        assert migrate.current(database) == revision
    migrate.downgrade(database, "base")
    assert _tables(database) == set() and migrate.current(database) is None
    migrate.upgrade(database)
    assert _tables(database) == set(Base.metadata.tables)
    database.dispose()


def test_sessions_are_measured_when_their_size_column_arrives(db_url):
    database = Database(db_url)
    migrate.upgrade(database)
    repo = repositories(database)
    repo["users"].add("alice")
    source, target = shape_id(), shape_id()
    for shape in (source, target):
        repo["shapes"].add(shape, 10, repo["users"].get("alice").id)
    record = session_record(source, target, owner="alice", curves=[curve("c1", 5), curve("c2", 40)])
    repo["sessions"].create(record)
    empty = session_record(source, target, owner="alice")
    repo["sessions"].create(empty)

    migrate.downgrade(database, "0001")  # a database of the first revision, with these sessions
    migrate.upgrade(database)
    assert repo["sessions"].read(record.id) == record  # nothing lost on the way (no cascade from a table copy)
    with database.read() as conn:
        measured = dict(conn.execute(select(m.Session.id, m.Session.bytes)).all())
    assert measured == {record.id: stored_bytes(record), empty.id: 0}
    assert stored_bytes(record) == 4 * (2 * 5 + 2 * 40 + 4 * 2)
    database.dispose()


def start_replica(url: str, go: Path, ready: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-c", REPLICA, url, str(go), str(ready)], stderr=subprocess.PIPE, text=True
    )


def test_replicas_starting_together_on_a_new_database_migrate_it_once(db_url, tmp_path):
    go = tmp_path / "go"
    ready = [tmp_path / f"ready-{n}" for n in range(REPLICAS)]
    replicas = [start_replica(db_url, go, path) for path in ready]
    while not all(path.exists() for path in ready):  # all past their imports: without the lock, they would race
        assert all(replica.poll() is None for replica in replicas), "a replica ended before it was ready"
        time.sleep(0.01)
    go.touch()
    for replica in replicas:
        assert replica.wait(timeout=300) == 0, replica.stderr.read() if replica.stderr else ""
    database = Database(db_url)
    assert migrate.current(database) == migrate.head()
    assert _tables(database) == set(Base.metadata.tables)
    with database.engine.connect() as conn:
        assert len(conn.exec_driver_sql("SELECT version_num FROM alembic_version").all()) == 1
    database.dispose()


@pytest.fixture
def postgresql_url(tmp_path):
    with fresh_database("postgresql", tmp_path) as url:
        yield url


def test_a_replica_waits_on_postgresql_while_another_holds_the_migration_lock(postgresql_url, tmp_path):
    database = Database(postgresql_url)
    go = tmp_path / "go"
    go.touch()
    with database.engine.connect() as holder:
        holder.execute(text("SELECT pg_advisory_lock(:key)"), {"key": migrate.MIGRATION_LOCK})
        replica = start_replica(postgresql_url, go, tmp_path / "ready")
        deadline = time.monotonic() + 120
        while not _waiting_for_the_lock(holder):
            assert replica.poll() is None, (
                f"it did not wait for the lock: {replica.stderr.read() if replica.stderr else ''}"
            )
            assert time.monotonic() < deadline, "the replica never asked for the migration lock"
            time.sleep(0.05)
        assert migrate.current(database) is None and _tables(database) == set()
        holder.execute(text("SELECT pg_advisory_unlock(:key)"), {"key": migrate.MIGRATION_LOCK})
        holder.commit()
    assert replica.wait(timeout=300) == 0, replica.stderr.read() if replica.stderr else ""
    assert migrate.current(database) == migrate.head()
    database.dispose()


def _waiting_for_the_lock(conn) -> bool:
    """Whether a session waits for the migration lock (PostgreSQL splits a bigint key into two 32-bit halves)."""
    query = "SELECT count(*) FROM pg_locks WHERE locktype = 'advisory' AND NOT granted AND objid = :key"
    return conn.execute(text(query), {"key": migrate.MIGRATION_LOCK}).scalar_one() > 0
