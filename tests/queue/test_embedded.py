"""The in-process executor (no Redis): same states as RQ, progress, deduplication, cancelling.

Failures are tested for both queues in test_failures.py."""

from __future__ import annotations

import time

import pytest

from curvefm.access import users_of
from curvefm.errors import Conflict, NotFound
from curvefm.service.demo import demo_shapes
from curvefm.store import Store
from curvefm.workers.embedded import EmbeddedQueue
from curvefm.workers.interface import JobInfo


@pytest.fixture
def store(tmp_path) -> Store:
    return Store(tmp_path / "data")


@pytest.fixture
def mesh_id(store) -> str:
    return store.put_mesh(demo_shapes()[0])


@pytest.fixture
def queue(store):
    queue = EmbeddedQueue(store.root, max_workers=1)
    yield queue
    queue.close()


def basis_job(store: Store, mesh_id: str, k: int) -> dict:
    return {
        "data_dir": str(store.root),
        "mesh_id": mesh_id,
        "k": k,
        "plugin": "laplace-beltrami",
        "params": {},
    }


def wait(queue: EmbeddedQueue, job_id: str, states=("finished", "failed", "canceled"), timeout=120) -> JobInfo:
    deadline = time.monotonic() + timeout
    while (info := queue.get(job_id)).state not in states:
        assert time.monotonic() < deadline, info
        time.sleep(0.02)
    return info


def test_finished_job_reports_progress_and_result(store, mesh_id, queue):
    info = wait(queue, queue.submit("basis", basis_job(store, mesh_id, 20)).id)
    assert (info.state, info.progress, info.result["k"]) == ("finished", 1.0, 20)
    assert info.started_at <= info.ended_at
    assert [b["k"] for b in store.stored_bases(mesh_id)] == [20]


def test_duplicate_requests_share_one_job(store, mesh_id, queue):
    first = queue.submit("basis", basis_job(store, mesh_id, 20), dedupe_key="basis-20")
    assert queue.submit("basis", basis_job(store, mesh_id, 20), dedupe_key="basis-20").id == first.id
    wait(queue, first.id)
    again = queue.submit("basis", basis_job(store, mesh_id, 20), dedupe_key="basis-20")
    assert again.id != first.id and wait(queue, again.id).state == "finished"  # the basis exists: at once


def test_cancel_queued_and_running_jobs(store, mesh_id, queue):
    running = queue.submit("basis", basis_job(store, mesh_id, 80))
    waiting = queue.submit("basis", basis_job(store, mesh_id, 40))
    wait(queue, running.id, states=("started",))

    assert queue.cancel(waiting.id).state == "canceled"
    assert "cancel requested" in queue.cancel(running.id).message
    assert wait(queue, running.id).state == "canceled"
    assert store.stored_bases(mesh_id) == []  # stopped before the basis was stored
    assert queue.cancel(running.id).state == "canceled"


def test_unknown_and_ended_jobs_are_typed_errors(store, queue):
    with pytest.raises(NotFound, match="no job with id 'nope'"):
        queue.get("nope")
    info = wait(queue, queue.submit("basis", basis_job(store, "feedbeef", 20)).id)
    assert info.state == "failed"
    with pytest.raises(Conflict, match="already failed"):
        queue.cancel(info.id)


def test_jobs_of_a_stopped_executor_are_lost_and_retried_by_the_next(store, mesh_id):
    if users_of(store.root).get("ada") is None:  # a job's owner is a user
        users_of(store.root).add("ada")
    stopped = EmbeddedQueue(store.root, max_workers=1)
    running = stopped.submit("basis", basis_job(store, mesh_id, 80), owner="ada")
    waiting = stopped.submit("basis", basis_job(store, mesh_id, 20))
    wait(stopped, running.id, states=("started",))
    stopped.close()
    for job in (running, waiting):
        assert stopped.get(job.id).state == "lost" and "the service stopped" in stopped.get(job.id).message

    queue = EmbeddedQueue(store.root, max_workers=1)  # the next process on the same data directory
    try:
        lost = queue.get(running.id)
        assert (lost.state, lost.owner) == ("lost", "ada") and "while the job was running" in lost.message
        assert "while the job was queued" in queue.get(waiting.id).message
        retry = queue.retry(waiting.id)
        assert retry.id != waiting.id and queue.retry(waiting.id).id == retry.id  # one retry while it runs
        assert wait(queue, retry.id).result["k"] == 20
        with pytest.raises(Conflict, match="only a lost, failed or canceled job"):
            queue.retry(retry.id)
        assert queue.retry(running.id).owner == "ada"
    finally:
        queue.close()
