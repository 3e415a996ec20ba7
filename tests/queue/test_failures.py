"""A failed job says why as data, a kind and one readable line, alike in the embedded executor and on RQ with a
real worker process; no traceback text is parsed, and none is part of what a job reports. Both queues keep a
job's owner."""

from __future__ import annotations

import time

import pytest

from curvefm.access import users_of
from curvefm.workers.embedded import EmbeddedQueue
from curvefm.workers.interface import JOB_KINDS, JobFailure, JobInfo, JobQueue
from curvefm.workers.jobs import JOB_FUNCTIONS


@pytest.fixture(params=["embedded", "redis"])
def queue(request, tmp_path) -> JobQueue:
    if request.param == "embedded":
        queue = EmbeddedQueue(tmp_path, max_workers=1)
    else:
        from curvefm.workers.rq_queue import RQQueue

        redis_url, prefix = request.getfixturevalue("redis_url"), request.getfixturevalue("redis_prefix")
        request.getfixturevalue("processes").worker(redis_url, prefix, "w1", data_dir=tmp_path)
        queue = RQQueue(redis_url, tmp_path, prefix=prefix, retries=0)
    yield queue
    queue.close()


def failed(queue: JobQueue, kwargs: dict, timeout: float = 120) -> JobInfo:
    job_id = queue.submit("basis", kwargs).id
    deadline = time.monotonic() + timeout
    while (info := queue.get(job_id)).state not in ("finished", "failed", "canceled"):
        assert time.monotonic() < deadline, info
        time.sleep(0.05)
    assert info.state == "failed", info
    return info


def test_a_project_error_keeps_its_kind_and_message(queue, tmp_path):
    info = failed(queue, {"data_dir": str(tmp_path), "mesh_id": "feedbeef", "k": 20})
    assert info.error == JobFailure("not_found", "no shape with id 'feedbeef'")


def test_any_other_exception_is_an_internal_failure_in_one_line(queue, tmp_path):
    info = failed(queue, {"data_dir": str(tmp_path), "mesh_id": "feedbeef", "k": 20, "colour": "red"})
    assert info.error.kind == "internal"
    assert info.error.message.startswith("TypeError: ") and "'colour'" in info.error.message
    assert "\n" not in info.error.message and "Traceback" not in info.error.message


def test_a_job_keeps_its_owner_and_a_joined_job_its_first_owner(queue, tmp_path):
    kwargs = {"data_dir": str(tmp_path), "mesh_id": "feedbeef", "k": 20}
    users = users_of(tmp_path)  # a job's owner is a user (on PostgreSQL, the module's database may have them)
    for name in ("alice", "bob"):
        if users.get(name) is None:
            users.add(name)
    first = queue.submit("basis", kwargs, dedupe_key="owned", owner="alice")
    joined = queue.submit("basis", kwargs, dedupe_key="owned", owner="bob")
    assert first.owner == "alice" and queue.get(first.id).owner == "alice"
    assert joined.owner == ("alice" if joined.id == first.id else "bob")  # joined alice's job, or it had ended
    assert queue.submit("basis", kwargs).owner is None


def test_every_job_kind_has_a_function():
    assert set(JOB_FUNCTIONS) == set(JOB_KINDS)
