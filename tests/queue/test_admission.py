"""A job's admission (its owner's concurrent-jobs quota) and its record are one transaction, on both queues: a
user's parallel submissions never pass the quota together, and a job that cannot be queued leaves no record. On
SQLite, and on PostgreSQL with ``CURVEFM_TEST_DATABASE=postgresql``; real Redis for the RQ queue (no worker runs,
so its jobs stay queued)."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from functools import partial

import pytest

from curvefm.errors import TooMany, Unavailable
from curvefm.records.engine import shared_database
from curvefm.records.usage import Limits, Quotas
from curvefm.records.users import Users
from curvefm.service.demo import demo_shapes
from curvefm.store import Store
from curvefm.workers.embedded import EmbeddedQueue
from curvefm.workers.interface import JobInfo, JobQueue
from curvefm.workers.rq_queue import RQQueue

SUBMISSIONS, QUOTA = 8, 3
BUSY_K = 300  # an admin's basis this large keeps the one embedded worker busy while the test submits


@pytest.fixture
def store(tmp_path) -> Store:
    return Store(tmp_path / "data")


@pytest.fixture(params=["embedded", "rq"])
def queue(request, store) -> Iterator[JobQueue]:
    if request.param == "rq":
        made: JobQueue = RQQueue(
            request.getfixturevalue("redis_url"), store.root, request.getfixturevalue("redis_prefix")
        )
    else:
        made = EmbeddedQueue(store.root, max_workers=1)
    yield made
    made.close()


def basis_kwargs(store: Store, mesh_id: str, k: int) -> dict:
    return {"data_dir": str(store.root), "mesh_id": mesh_id, "k": k, "plugin": "laplace-beltrami", "params": {}}


def occupy_the_worker(queue: JobQueue, store: Store, mesh_id: str) -> None:
    """The embedded queue runs jobs at once: an admin's long job keeps its one thread, so later jobs stay queued."""
    if isinstance(queue, EmbeddedQueue):
        busy = queue.submit("basis", basis_kwargs(store, mesh_id, BUSY_K), owner="root")
        assert queue.get(busy.id).state in ("queued", "started")


def test_parallel_submissions_of_one_user_admit_exactly_the_quota(queue, store):
    database = shared_database(store.root)
    users = Users(database)
    users.add("alice")
    users.add("root", admin=True)
    alice = users.get("alice")
    quotas = Quotas(database, Limits(jobs=QUOTA))
    mesh_id = store.put_mesh(demo_shapes()[0])
    occupy_the_worker(queue, store, mesh_id)
    admitted: list[JobInfo] = []
    refused: list[TooMany] = []
    start = threading.Barrier(SUBMISSIONS)

    def submit(k: int) -> None:
        start.wait()
        try:
            admit = partial(quotas.admit, alice, "jobs")
            admitted.append(queue.submit("basis", basis_kwargs(store, mesh_id, k), owner="alice", admit=admit))
        except TooMany as exc:
            refused.append(exc)

    threads = [threading.Thread(target=submit, args=(20 + k,)) for k in range(SUBMISSIONS)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()

    assert len(admitted) == QUOTA and len(refused) == SUBMISSIONS - QUOTA
    assert all(error.setting == "CURVEFM_QUOTA_JOBS" for error in refused)
    stored = queue.records.rows.of_owner(alice.id)  # a refused submission stored nothing
    assert sorted(job.id for job in stored) == sorted(info.id for info in admitted)
    assert quotas.usage(alice.id).active_jobs == QUOTA


def test_a_job_redis_does_not_take_leaves_no_record(private_redis, store):
    queue = RQQueue(private_redis.url(), store.root)
    Users(queue.records.db).add("alice")
    private_redis.stop()
    try:
        with pytest.raises(Unavailable, match="Redis"):
            queue.submit("refine", {"data_dir": str(store.root)}, owner="alice")
    finally:
        queue.close()
    assert queue.records.rows.of_owner(Users(queue.records.db).get("alice").id) == []
