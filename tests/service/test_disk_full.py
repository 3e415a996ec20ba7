"""A full disk, on a real server whose data directory is a small tmpfs the test fills: every write answers 507
naming the disk (no 500, no traceback), jobs end instead of hanging (in-process or on RQ; their records catch up),
the command line says so in one line, and once space is freed everything acknowledged before is there and the
service works again without a restart. A PostgreSQL server's own disk cannot
be filled here: there the server is made to raise its disk-full error (SQLSTATE 53100) from a trigger."""

from __future__ import annotations

import contextlib
import errno
import os
import re
import sqlite3
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from support.ci import unavailable
from support.errors import DATABASE, expect
from support.records import fresh_database

from curvefm.geometry import save_mesh
from curvefm.geometry.validation import build_mesh
from curvefm.records import Database
from curvefm.service.demo import demo_shapes

DISK_MB = 48
K = 20
FULL = "the data directory's disk is full"
FILLER = "filler"


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A tmpfs of ``DISK_MB`` MB mounted for this test (root only), unmounted afterwards."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if os.geteuid() != 0:
        unavailable("mounting a tmpfs to fill needs root")
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={DISK_MB}m", "tmpfs", str(disk)], capture_output=True, text=True
    )
    if mounted.returncode != 0:
        unavailable(f"cannot mount a tmpfs: {mounted.stderr.strip()}")
    try:
        yield disk
    finally:
        subprocess.run(["umount", "--lazy", str(disk)], check=True)


def fill(disk: Path) -> None:
    """Write a file until the disk refuses another byte."""
    with open(disk / FILLER, "wb", buffering=0) as f:
        chunk = b"\0" * (1 << 20)
        while chunk:
            try:
                f.write(chunk)
            except OSError as exc:
                assert exc.errno == errno.ENOSPC, exc
                chunk = chunk[: len(chunk) // 2]


def free(disk: Path) -> None:
    (disk / FILLER).unlink()


def new_shape(folder: Path) -> Path:
    """A mesh the server has not stored (so storing it needs space)."""
    source = demo_shapes()[0]
    path = folder / "new.off"
    save_mesh(build_mesh(source.vertices * 1.5, source.faces, name="new"), path)
    return path


def upload(api, path: Path):
    with open(path, "rb") as f:
        return api.client.post("/shapes", files={"file": (path.name, f)})


def documents_507(api, request) -> bool:
    """Whether the published schema lists 507 for the operation ``request`` reached."""
    paths = api.client.get("/openapi.json").raise_for_status().json()["paths"]
    route = next(p for p in paths if re.fullmatch(re.sub(r"\{[^}]+\}", "[^/]+", p), request.url.path))
    return "507" in paths[route][request.method.lower()]["responses"]


def add_curve(api, session_id: str, vertex: int):
    path = [vertex, vertex + 50]
    return api.client.post(f"/sessions/{session_id}/curves", json={"source": path, "target": path})


@pytest.mark.sqlite_only  # the database is the data directory's file; PostgreSQL's disk is its own
def test_full_disk_answers_507_and_loses_nothing(small_disk, processes, tmp_path):
    api = processes.api(small_disk / "data")
    shapes, session_id = api.demo_pair(tmp_path, K)
    curves = [add_curve(api, session_id, v).raise_for_status().json()["curve"] for v in (10, 200, 3000)]
    new_mesh = new_shape(tmp_path)

    fill(small_disk)
    refused = {
        "upload": upload(api, new_mesh),
        "session": api.client.post("/sessions", json={"source": shapes[0], "target": shapes[1], "k": K}),
        "curve": add_curve(api, session_id, 500),
        "curve edit": api.client.put(
            f"/sessions/{session_id}/curves/{curves[0]['id']}", json={"source": [11, 61], "target": [11, 61]}
        ),
        "basis job": api.client.post(f"/shapes/{shapes[0]}/bases", json={"k": K + 5}),
        "collection": api.client.post("/collections", json={"template": shapes[0], "k": K}),
    }
    for what, response in refused.items():
        body = expect(response, 507, "disk_full", FULL)
        assert str(small_disk) not in body["detail"], what
        assert documents_507(api, response.request), what
    assert api.client.get(f"/sessions/{session_id}").raise_for_status().json()["curves"] == curves  # reads go on
    assert api.client.get(f"/sessions/{session_id}/map").status_code == 200
    assert api.client.get(f"/sessions/{session_id}/transfer", params={"function": "xyz"}).status_code == 200

    free(small_disk)
    stored = api.client.get(f"/sessions/{session_id}").raise_for_status().json()["curves"]
    assert stored == curves
    assert upload(api, new_mesh).status_code == 201
    assert add_curve(api, session_id, 500).status_code == 201
    job = api.client.post(f"/shapes/{shapes[0]}/bases", json={"k": K + 5}).raise_for_status().json()
    assert api.wait_job(job["id"])["state"] == "finished"
    log = api.log.read_text()
    assert "Traceback" not in log and " 500 " not in log, log[-3000:]
    assert FULL in log  # the operator is told


@pytest.mark.sqlite_only
def test_the_command_line_names_a_full_disk(small_disk):
    data = small_disk / "data"
    add = [sys.executable, "-m", "curvefm.cli", "users", "add", "--data", str(data)]
    subprocess.run([*add, "alice"], check=True, capture_output=True)
    fill(small_disk)
    refused = subprocess.run([*add, "bob"], capture_output=True, text=True)
    assert refused.returncode == 2 and refused.stderr.startswith(f"curvefm: error: {FULL}"), refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1  # no traceback
    free(small_disk)
    subprocess.run([*add, "bob"], check=True, capture_output=True)


BUSY_K = 500  # seconds of work per job: both executor threads stay busy while the disk is filled
JOB_SLOTS = 3


def upload_demo_shapes(api, folder: Path) -> list[str]:
    paths = []
    for mesh in demo_shapes():
        paths.append(folder / f"{mesh.name}.off")
        save_mesh(mesh, paths[-1])
    return [api.upload(path) for path in paths]


def recorded_state(data_dir: Path, job_id: str) -> str:
    with contextlib.closing(sqlite3.connect(f"file:{data_dir / DATABASE}?mode=ro", uri=True)) as conn:
        return conn.execute("SELECT state FROM jobs WHERE id = ?", (job_id,)).fetchone()[0]


def wait_recorded(data_dir: Path, job_id: str, state: str, timeout: float = 60) -> None:
    deadline = time.monotonic() + timeout
    while recorded_state(data_dir, job_id) != state:
        assert time.monotonic() < deadline, f"job {job_id}'s record is still {recorded_state(data_dir, job_id)}"
        time.sleep(0.2)


@pytest.mark.sqlite_only
def test_in_process_job_ends_when_its_record_cannot_be_written(small_disk, processes, tmp_path):
    data = small_disk / "data"
    api = processes.api(data, env={"CURVEFM_QUOTA_JOBS": str(JOB_SLOTS)})
    shapes = upload_demo_shapes(api, tmp_path)
    busy = [api.client.post(f"/shapes/{s}/bases", json={"k": BUSY_K}).raise_for_status().json() for s in shapes]
    for job in busy:
        api.wait_job(job["id"], until=("started",))
    waiting = api.client.post(f"/shapes/{shapes[0]}/bases", json={"k": K}).raise_for_status().json()
    assert waiting["state"] == "queued"

    fill(small_disk)  # the waiting job's "started" record cannot be written, nor the busy jobs' progress
    for job in [*busy, waiting]:
        ended = api.wait_job(job["id"])
        assert ended["state"] == "failed" and ended["error"]["kind"] == "disk_full", ended
        assert FULL in ended["error"]["message"]
    expect(api.client.delete(f"/jobs/{waiting['id']}"), 409, "conflict", "already failed")  # not "cancel requested"
    assert recorded_state(data, waiting["id"]) == "queued"  # the disk is full: the record waits

    free(small_disk)
    for job in [*busy, waiting]:
        wait_recorded(data, job["id"], "failed")  # the job slots are free again
    again = [api.client.post(f"/shapes/{s}/bases", json={"k": K}).raise_for_status().json() for s in shapes]
    assert waiting["id"] not in {job["id"] for job in again}  # not absorbed by the failed job
    assert all(api.wait_job(job["id"])["state"] == "finished" for job in again)
    assert "Traceback" not in api.log.read_text()


DISK_FULL_ON = """
CREATE FUNCTION disk_full() RETURNS trigger LANGUAGE plpgsql AS
$$ BEGIN RAISE EXCEPTION 'could not extend file' USING ERRCODE = 'disk_full'; END $$;
CREATE TRIGGER shapes_disk_full BEFORE INSERT ON shapes FOR EACH ROW EXECUTE FUNCTION disk_full();
CREATE TRIGGER jobs_disk_full BEFORE INSERT ON jobs FOR EACH ROW EXECUTE FUNCTION disk_full();
"""
DISK_FULL_OFF = "DROP FUNCTION disk_full() CASCADE"


def test_postgresql_disk_full_answers_507(processes, tmp_path, monkeypatch):
    with fresh_database("postgresql", tmp_path) as url:
        monkeypatch.setenv("CURVEFM_DATABASE_URL", url)  # this test's users, and the server's records
        api = processes.api(tmp_path / "data", env={"CURVEFM_DATABASE_URL": url})
        kept = api.upload(new_shape(tmp_path))
        database = Database(url)
        with database.write() as conn:
            conn.exec_driver_sql(DISK_FULL_ON)
        source = demo_shapes()[0]
        save_mesh(source, tmp_path / "demo.off")
        expect(upload(api, tmp_path / "demo.off"), 507, "disk_full", "the records' database server's disk is full")
        basis = api.client.post(f"/shapes/{kept}/bases", json={"k": K})
        expect(basis, 507, "disk_full", "the records' database server's disk is full")

        with database.write() as conn:
            conn.exec_driver_sql(DISK_FULL_OFF)
        database.dispose()
        stored = upload(api, tmp_path / "demo.off").raise_for_status().json()["id"]
        assert {kept, stored} <= {shape["id"] for shape in api.client.get("/shapes").raise_for_status().json()}
        assert "Traceback" not in api.log.read_text()


@pytest.mark.sqlite_only
def test_rq_jobs_end_and_their_records_catch_up(small_disk, processes, tmp_path, redis_url, redis_prefix):
    data = small_disk / "data"
    api = processes.api(data, redis_url, env={"CURVEFM_QUEUE_PREFIX": redis_prefix})
    processes.worker(redis_url, redis_prefix, "only")
    shapes = upload_demo_shapes(api, tmp_path)
    busy = api.client.post(f"/shapes/{shapes[0]}/bases", json={"k": BUSY_K}).raise_for_status().json()
    api.wait_job(busy["id"], until=("started",))
    waiting = api.client.post(f"/shapes/{shapes[1]}/bases", json={"k": K}).raise_for_status().json()

    fill(small_disk)  # the worker can write neither the busy job's basis nor the waiting job's "started"
    for job in (busy, waiting):
        ended = api.wait_job(job["id"])  # answered from Redis while the records cannot be written
        assert ended["state"] == "failed" and ended["error"]["kind"] == "disk_full", ended

    free(small_disk)
    for job in (busy, waiting):
        wait_recorded(data, job["id"], "failed")  # caught up by the API without anyone asking
    assert "Traceback" not in api.log.read_text()
