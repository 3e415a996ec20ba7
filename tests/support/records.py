"""What the records' tests share: making and dropping a test database, and small records to store."""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import time
from array import array
from collections.abc import Iterator
from pathlib import Path

import pytest

POSTGRES = os.environ.get("CURVEFM_TEST_POSTGRES", "postgresql://postgres@127.0.0.1:5432/test")


@contextlib.contextmanager
def fresh_database(kind: str, folder: Path) -> Iterator[str]:
    """A URL of a new, empty database of ``kind``, dropped afterwards."""
    if kind == "sqlite":
        yield f"sqlite:///{folder / 'curvefm.db'}"
        return
    name = f"curvefm_test_{secrets.token_hex(6)}"
    with _postgres_admin() as admin:
        admin.execute(f'CREATE DATABASE "{name}"')
        try:
            yield f"{_postgres_base()}/{name}"
        finally:
            admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


class MigratedTemplates:
    """Per engine, one database migrated to the newest schema (made on first use, dropped by :meth:`drop_all`), of
    which each test gets a fresh copy: a copy costs a file copy or a ``CREATE DATABASE ... TEMPLATE`` where running
    every migration again would cost far more (the migrations themselves are tested on empty databases)."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.urls: dict[str, str] = {}

    def template(self, kind: str) -> str:
        if kind not in self.urls:
            from curvefm.records import open_database

            url = self.urls[kind] = self._create(kind, f"curvefm_template_{secrets.token_hex(6)}")
            open_database(url=url).dispose()  # migrated; no connection left, as a template database needs
        return self.urls[kind]

    def _create(self, kind: str, name: str, template: str | None = None) -> str:
        if kind == "sqlite":
            return f"sqlite:///{self.folder / f'{name}.db'}"
        with _postgres_admin() as admin:
            admin.execute(f'CREATE DATABASE "{name}"' + (f' TEMPLATE "{template}"' if template else ""))
        return f"{_postgres_base()}/{name}"

    @contextlib.contextmanager
    def copy(self, kind: str, folder: Path) -> Iterator[str]:
        """A URL of a new database of ``kind`` at the newest schema, with no rows; dropped afterwards."""
        template = self.template(kind)
        if kind == "sqlite":
            copied = folder / "curvefm.db"
            shutil.copyfile(template.removeprefix("sqlite:///"), copied)
            yield f"sqlite:///{copied}"
            return
        name = f"curvefm_test_{secrets.token_hex(6)}"
        url = self._create(kind, name, template=template.rsplit("/", 1)[1])
        try:
            yield url
        finally:
            with _postgres_admin() as admin:
                admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')

    def drop_all(self) -> None:
        if "postgresql" in self.urls:
            with _postgres_admin() as admin:
                admin.execute(f'DROP DATABASE IF EXISTS "{self.urls["postgresql"].rsplit("/", 1)[1]}" WITH (FORCE)')
        self.urls.clear()


def _postgres_base() -> str:
    return POSTGRES.rsplit("/", 1)[0].replace("postgresql://", "postgresql+psycopg://", 1)


def _postgres_admin():
    """An autocommit connection to the server's maintenance database; without the server a skip."""
    psycopg = pytest.importorskip("psycopg")
    try:
        return psycopg.connect(POSTGRES, autocommit=True, connect_timeout=3)
    except psycopg.OperationalError as exc:
        pytest.skip(f"no PostgreSQL at {POSTGRES}: {exc}")


class Databases:
    """The databases of one test module's data directories on a PostgreSQL server (``CURVEFM_TEST_DATABASE=
    postgresql``): each data directory (each deployment a test starts) gets a database of its own, made on its first
    use and dropped by :meth:`drop_all`; the processes that share a data directory (replicas, workers, the test
    process itself) share its database."""

    def __init__(self, admin) -> None:
        self.admin = admin  # an autocommit connection to the server's maintenance database
        self.base = _postgres_base()
        self.urls: dict[Path, str] = {}

    @classmethod
    def connect(cls) -> Databases:
        """The server's databases; without the server (or psycopg) a skip, a failure naming it under CI."""
        from support.ci import unavailable

        try:
            import psycopg
        except ImportError:
            unavailable("psycopg is not installed (the 'postgresql' extra; scripts/setup.sh test installs it)")
        try:
            return cls(psycopg.connect(POSTGRES, autocommit=True, connect_timeout=3))
        except psycopg.OperationalError as exc:
            unavailable(f"no PostgreSQL at {POSTGRES} ({exc}); scripts/services.sh starts one")

    def url(self, data_dir: str | os.PathLike[str]) -> str:
        """The URL of the data directory's database (made now if it is new)."""
        key = Path(data_dir).resolve()
        if key not in self.urls:
            name = f"curvefm_test_{secrets.token_hex(6)}"
            self.admin.execute(f'CREATE DATABASE "{name}"')
            self.urls[key] = f"{self.base}/{name}"
        return self.urls[key]

    def drop_all(self) -> None:
        from curvefm.records import engine

        with engine._shared_lock:  # this process's engines first, so that nothing holds a connection
            for url in self.urls.values():
                database = engine._shared.pop(url, None)
                if database is not None:
                    database.engine.dispose()
        with self.admin:
            for url in self.urls.values():
                self.admin.execute(f'DROP DATABASE IF EXISTS "{url.rsplit("/", 1)[1]}" WITH (FORCE)')
        self.urls.clear()


current: Databases | None = None
"""The running module's :class:`Databases` (None: each data directory keeps its SQLite file)."""


def database_env(data_dir: str | os.PathLike[str]) -> dict[str, str]:
    """The environment that points a process (an API, a worker, the CLI) at the data directory's test database:
    ``CURVEFM_DATABASE_URL`` on PostgreSQL, nothing on SQLite."""
    return {"CURVEFM_DATABASE_URL": current.url(data_dir)} if current is not None else {}


def shape_id() -> str:
    return secrets.token_hex(8)


def path(*ids: int) -> array:
    return array("i", ids)


def curve(curve_id: str, n: int = 3, template_curve: str | None = None):
    from curvefm.session.record import CurveRecord

    return CurveRecord(
        id=curve_id,
        spec={"source": [0, n], "target": [1, n + 1], "template_curve": template_curve},
        tracer="geodesic",
        path_source=path(*range(n)),
        path_target=path(*range(1, n + 1)),
    )


def session_record(source: str, target: str, owner: str = "", curves=(), session_id: str | None = None, **changes):
    from curvefm.session.record import SessionRecord

    moment = time.time()
    fields = dict(
        id=session_id or secrets.token_hex(8),
        name="a pair",
        owner=owner,
        sharing="private",
        source=source,
        target=target,
        k=30,
        alpha=1e-3,
        samples=100,
        energy="combined",
        tracer="geodesic",
        basis_plugin="laplace-beltrami",
        basis_params={"normalize": True},
        curves=list(curves),
        next_curve=len(curves) + 1,
        created_at=moment,
        updated_at=moment,
    )
    fields.update(changes)
    return SessionRecord(**fields)


def collection_record(template: str, owner: str = "", collection_id: str | None = None, **changes):
    from curvefm.collection.record import CollectionRecord, TemplateCurve

    moment = time.time()
    fields = dict(
        id=collection_id or secrets.token_hex(8),
        name="a collection",
        owner=owner,
        sharing="private",
        template=template,
        k=30,
        alpha=1e-3,
        samples=100,
        energy="combined",
        tracer="geodesic",
        basis_plugin="laplace-beltrami",
        basis_params={},
        curves=[TemplateCurve(id="t1", name="spine", waypoints=[0, 5], path=path(0, 1, 2, 5))],
        created_at=moment,
        updated_at=moment,
    )
    fields.update(changes)
    return CollectionRecord(**fields)


def repositories(db):
    """Every repository on ``db``, by name."""
    from curvefm.records.audit import AuditLog
    from curvefm.records.collections import Collections
    from curvefm.records.jobs import Jobs
    from curvefm.records.sessions import Sessions
    from curvefm.records.shapes import Shapes
    from curvefm.records.users import Users

    sessions = Sessions(db)
    return dict(
        users=Users(db),
        shapes=Shapes(db),
        sessions=sessions,
        collections=Collections(db, sessions),
        jobs=Jobs(db),
        audit=AuditLog(db),
    )


def job_row(job_id: str | None = None, owner: str | None = None, state: str = "queued", **changes):
    from curvefm.records.jobs import JobRow

    fields = dict(
        id=job_id or secrets.token_hex(8),
        kind="refine",
        state=state,
        created_at=time.time(),
        owner=owner,
        kwargs={"data_dir": "/data", "session": {"id": "x"}},
        dedupe_key=None,
    )
    fields.update(changes)
    return JobRow(**fields)


def add_curves(url: str, session_id: str, prefix: str, count: int) -> list[str]:
    """Add ``count`` curves to the session, each an edit of its own retried on a stale revision, as a request of
    the service would; returns the ids of the curves whose write was acknowledged. Runs in a thread or a process."""
    from curvefm.records import Database
    from curvefm.records.sessions import Sessions, StaleRevision

    database = Database(url)
    sessions = Sessions(database)
    acknowledged = []
    try:
        for i in range(count):
            curve_id = f"{prefix}{i}"
            while True:
                current = sessions.read(session_id)
                edited = current.model_copy(
                    update={"curves": [*current.curves, curve(curve_id)], "next_curve": current.next_curve + 1}
                )
                try:
                    sessions.write(edited, base=current)
                except StaleRevision:
                    continue
                acknowledged.append(curve_id)
                break
    finally:
        database.dispose()
    return acknowledged
