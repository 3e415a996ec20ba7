"""The records' database budgets (issue 31), on SQLite and PostgreSQL, printed as JSON:

* a page of 50 sessions with 1,000 and with 10,000 sessions of 10 curves in the database (a user's view: their own
  and the lab's shared ones; an admin's: all): p95 <= 50 ms, and the memory a page takes (tracemalloc's peak)
  independent of the number of records;
* one curve edit's write (a session of 45 curves of 300 vertices a side, one curve replaced): median <= 3 ms, with
  each commit's durability setting: SQLite ``synchronous`` FULL (the default) and NORMAL, PostgreSQL's
  ``synchronous_commit`` on (the server's default) and off.

Usage::

    python -m benchmarks.bench_records [--engines sqlite,postgresql] [--postgres postgresql://postgres@127.0.0.1/test]

PostgreSQL: a database ``curvefm_bench_<random>`` is made on that server and dropped afterwards. Run it on an
idle machine: the numbers are latencies.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import secrets
import statistics
import time
import tracemalloc
from array import array
from collections.abc import Iterator

from sqlalchemy import insert

from benchmarks.common import machine, scratch_database
from curvefm.records import Database, Viewer, open_database
from curvefm.records import models as m
from curvefm.records.engine import SYNCHRONOUS_VARIABLE
from curvefm.records.sessions import Sessions
from curvefm.records.shapes import Shapes
from curvefm.records.users import Users
from curvefm.session.record import CurveRecord, SessionRecord

SIZES, USERS, PAGE, CURVES_PER_SESSION = (1_000, 10_000), 20, 50, 10
DURABILITY = {"sqlite": ("FULL", "NORMAL"), "postgresql": ("on", "off")}


@contextlib.contextmanager
def opened(engine: str, url: str, durability: str) -> Iterator[Database]:
    """The database with one commit durability: SQLite's ``synchronous`` by curvefm's own setting, PostgreSQL's
    ``synchronous_commit`` for this connection (what an operator sets on the server or the database)."""
    if engine == "postgresql":
        url += f"?options=-c%20synchronous_commit%3D{durability}"
    os.environ[SYNCHRONOUS_VARIABLE] = durability if engine == "sqlite" else "FULL"  # read as the engine is made
    database = open_database(url=url)
    try:
        yield database
    finally:
        database.dispose()


def curve(curve_id: str, n: int) -> CurveRecord:
    return CurveRecord(
        id=curve_id,
        spec={"source": [0, n - 1], "target": [0, n - 1]},
        tracer="geodesic",
        path_source=array("i", range(n)),
        path_target=array("i", range(n)),
    )


def quantiles(times: list[float]) -> dict[str, float]:
    times = sorted(times)
    p95 = times[min(len(times) - 1, int(0.95 * len(times)))]
    return {"median_ms": round(1e3 * statistics.median(times), 3), "p95_ms": round(1e3 * p95, 3)}


def fill(database: Database, owners: list[int], shapes: tuple[str, str], first: int, count: int) -> None:
    """Sessions ``first`` .. ``first + count`` (one in ten shared read), each with 10 curves of 100 vertices."""
    now, path = time.time(), array("i", range(100)).tobytes()
    sessions, curves = [], []
    for i in range(first, first + count):
        session_id = secrets.token_hex(8)
        sessions.append(session_row(session_id, i, owners[i % len(owners)], shapes, now))
        curves += [
            dict(session_id=session_id, id=f"c{j}", position=j, spec={"source": [0, 99], "target": [0, 99]},
                 tracer="geodesic", path_source=path, path_target=path)
            for j in range(CURVES_PER_SESSION)
        ]  # fmt: skip
    with database.write() as conn:
        conn.execute(insert(m.Session), sessions)
        conn.execute(insert(m.Curve), curves)


def session_row(session_id: str, i: int, owner: int, shapes: tuple[str, str], now: float) -> dict:
    return dict(
        id=session_id,
        name=f"session {i}",
        owner_id=owner,
        sharing="read" if i % 10 == 0 else "private",
        source=shapes[0],
        target=shapes[1],
        k=60,
        alpha=1e-3,
        samples=100,
        energy="combined",
        tracer="geodesic",
        basis_plugin="laplace-beltrami",
        basis_params={},
        next_curve=CURVES_PER_SESSION + 1,
        revision=0,
        created_at=now - i,
        updated_at=now - i,
    )


def pages(database: Database, viewer: Viewer, repeats: int) -> dict:
    """Page timings (pages 1 to 10 in turn) and the memory one page takes."""
    sessions, times = Sessions(database), []
    for i in range(repeats):
        started = time.perf_counter()
        page = sessions.page(viewer, limit=PAGE, offset=(i % 10) * PAGE)
        times.append(time.perf_counter() - started)
    tracemalloc.start()
    sessions.page(viewer, limit=PAGE, offset=0)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return {"visible": page.total, **quantiles(times), "page_peak_kib": round(peak / 1024, 1)}


def edit_writes(database: Database, owner: str, shapes: tuple[str, str], repeats: int) -> dict:
    sessions, now = Sessions(database), time.time()
    record = SessionRecord(
        id=secrets.token_hex(8),
        owner=owner,
        source=shapes[0],
        target=shapes[1],
        k=60,
        alpha=1e-3,
        samples=100,
        tracer="geodesic",
        basis_plugin="laplace-beltrami",
        basis_params={},
        curves=[curve(f"c{i}", 300) for i in range(1, 46)],
        next_curve=46,
        created_at=now,
        updated_at=now,
    )
    sessions.create(record)
    current, times = sessions.read(record.id), []
    for i in range(repeats):
        edited = current.model_copy(update={"curves": [*current.curves[:-1], curve(f"x{i}", 300)]})
        started = time.perf_counter()
        current = sessions.write(edited, base=current)
        times.append(time.perf_counter() - started)
    return quantiles(times)


def bench(engine: str, postgres: str, repeats: int) -> list[dict]:
    results = []
    with scratch_database(engine, postgres) as url:
        default, other = DURABILITY[engine]
        with opened(engine, url, default) as database:
            users = Users(database)
            for i in range(USERS):
                users.add(f"user{i}")
            owners = [user.id for user in users.list()]
            shapes = (secrets.token_hex(8), secrets.token_hex(8))
            for shape in shapes:
                Shapes(database).add(shape, 1, owners[0])
            filled = 0
            for size in SIZES:
                fill(database, owners, shapes, filled, size - filled)
                filled = size
                for who, viewer in (("user", Viewer(owners[1])), ("admin", Viewer(None, admin=True))):
                    results.append({"engine": engine, "measure": "page", "sessions": size, "viewer": who,
                                    **pages(database, viewer, repeats)})  # fmt: skip
        for durability in (default, other):
            with opened(engine, url, durability) as database:
                timing = edit_writes(database, "user0", shapes, repeats)
                results.append({"engine": engine, "measure": "edit_write", "durability": durability, **timing})
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--engines", default="sqlite,postgresql")
    parser.add_argument("--postgres", default="postgresql://postgres@127.0.0.1:5432/test")
    parser.add_argument("--repeats", type=int, default=200)
    args = parser.parse_args()
    started = time.time()
    results = [row for engine in args.engines.split(",") for row in bench(engine, args.postgres, args.repeats)]
    report = {
        "benchmark": "records",
        **machine(),
        "load_average_at_start": os.getloadavg()[0],
        "seconds": round(time.time() - started, 1),
        "targets": {"page_p95_ms": 50, "edit_write_median_ms": 3},
        "results": results,
    }
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
