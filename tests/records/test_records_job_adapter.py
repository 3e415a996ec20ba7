"""``DbJobRecords``, the queues' job records, on both engines: the script the file ``JobRecords`` it replaced
passed, with the same answers."""

from __future__ import annotations

import time

import pytest

from curvefm.records import open_database
from curvefm.workers.interface import JobFailure, JobInfo
from curvefm.workers.job_rows import DbJobRecords, StoredJob


@pytest.fixture(params=["sqlite", "postgresql"])
def records(request, tmp_path, migrated_templates):
    with migrated_templates.copy(request.param, tmp_path) as url:
        database = open_database(url=url)
        yield DbJobRecords(database=database)
        database.dispose()


def test_the_same_answers_as_the_file_records(records, tmp_path):
    job = StoredJob(JobInfo("j1", "basis", "queued", created_at=1.0), {"data_dir": str(tmp_path), "k": 20}, "basis:x")
    records.create(job)
    records.create(StoredJob(JobInfo("j2", "refine", "queued", created_at=2.0), {"n": 1}, None, "rq"))
    assert records.load("j1") == job
    assert sorted(s.info.id for s in records.unended()) == ["j1", "j2"]
    assert records.update("j1", state="started", worker="w").worker == "w"
    assert records.lose("j1", "Redis restarted").state == "lost"
    assert records.update("j1", state="started").state == "lost"
    assert records.update("j1", progress=0.5, message="computing").message == "Redis restarted"
    assert records.update("j1", state="finished", result={"k": 20}).state == "finished"
    assert records.lose("j1", "again").state == "finished"  # an ended job is never declared lost
    stored = records.load("j1")
    assert (stored.kwargs["k"], stored.dedupe_key, stored.info.result) == (20, "basis:x", {"k": 20})
    assert records.load("../j1") is None and records.load("nope") is None
    assert records.update("nope", state="started") is None and records.lose("nope", "x") is None
    failed = records.update("j2", state="failed", error=JobFailure("internal", "it broke"), ended_at=time.time())
    assert failed.error == JobFailure("internal", "it broke")
    assert records.load("j2").info == failed and records.load("j2").runner == "rq"
    assert records.unended() == []
    records.update("j1", ended_at=10.0)  # an ended job's times stay as they ended
    assert records.load("j1").info.ended_at > 10.0
    records.create(StoredJob(JobInfo("j3", "basis", "queued"), {}, None))
    assert records.expire(ended_before=time.time() + 1) == ["j1", "j2"]
    records.delete("j3")
    assert records.load("j1") is None and records.load("j3") is None
