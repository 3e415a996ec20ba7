"""Jobs state their time limit and peak memory from their meshes, with real Redis and real worker processes: a job
over a worker's memory budget fails ``too_large`` before it loads anything (and is refused at submission once no
worker of its queue could take it), a job past its time limit fails ``timeout``, a work horse killed as the
kernel's OOM killer kills fails ``killed`` naming the signal and the memory, and the in-process executor applies
the same budget and limits."""

from __future__ import annotations

import os
import signal
import time

import pytest
from support.errors import expect
from support.processes import descendants

from curvefm.errors import ResourceLimit
from curvefm.geometry import build_mesh, load_mesh
from curvefm.store import Store
from curvefm.workers.embedded import EmbeddedQueue
from curvefm.workers.interface import JobInfo, JobQueue
from curvefm.workers.sizing import DEFAULT_SIZING, MEMORY_SETTING, JobSizing, demand, job_demand

SLOW_K = 500  # a FAUST basis this large takes 5-15 s: time to see it started and to stop it
SMALL_BUDGET = "64M"  # below any job's stated memory (the interpreter and libraries alone are more)
ONE_SECOND = JobSizing(timeout_floor_s=1, timeout_factor=1e-9)


@pytest.fixture
def store(tmp_path, shared_data) -> Store:
    return Store(tmp_path / "data")


@pytest.fixture
def faust_id(store, shared_data) -> str:
    return store.put_mesh(load_mesh(shared_data / "faust" / "tr_reg_000.off"))


def rq_queue(request, store: Store, sizing: JobSizing = DEFAULT_SIZING, retries: int = 1):
    from curvefm.workers.rq_queue import RQQueue

    redis_url, prefix = request.getfixturevalue("redis_url"), request.getfixturevalue("redis_prefix")
    return RQQueue(redis_url, store.root, prefix=prefix, retries=retries, sizing=sizing)


def start_worker(request, store: Store, name: str, **env: str):
    redis_url, prefix = request.getfixturevalue("redis_url"), request.getfixturevalue("redis_prefix")
    return request.getfixturevalue("processes").worker(redis_url, prefix, name, data_dir=store.root, env=env)


def basis(store: Store, mesh_id: str, k: int) -> dict:
    return {"data_dir": str(store.root), "mesh_id": mesh_id, "k": k}


def wait(queue: JobQueue, job_id: str, until=("finished", "failed", "canceled", "lost"), timeout=120) -> JobInfo:
    deadline = time.monotonic() + timeout
    while (info := queue.get(job_id)).state not in until:
        assert time.monotonic() < deadline, info
        time.sleep(0.05)
    return info


def test_the_estimates_cover_the_measured_peaks():
    """The peaks of docs/performance.md ("Job sizes"): the basis pipeline at k = 120, exact and multiresolution, and
    curvefm match on a pair (the vertices of both shapes; bases one after the other above a million)."""
    gib = 2**30
    exact = {6_890: 0.16, 110_210: 0.77, 440_834: 2.53}
    approximate = {110_210: 0.62, 440_834: 1.76}
    pairs = {2 * 110_210: 1.7, 2 * 440_834: 6.4, 2 * 1_763_330: 10.17}
    for vertices, peak in exact.items():
        assert demand("basis", vertices, 120, JobSizing()).memory_bytes > peak * gib * 1.2, vertices
    for vertices, peak in approximate.items():
        assert demand("basis", vertices, 120, JobSizing(), approximate=True).memory_bytes > peak * gib * 1.2, vertices
    for vertices, peak in pairs.items():
        assert demand("refine", vertices, 120, JobSizing()).memory_bytes > peak * gib * 1.2, vertices


def test_a_big_multiresolution_basis_states_less_than_an_exact_one(store, shared_data):
    """A laplace-beltrami basis job of a mesh past the multiresolution threshold states the multiresolution fit
    unless its parameters ask for the exact solver; another basis plugin states the exact fit."""
    import trimesh

    mesh = load_mesh(shared_data / "faust" / "tr_reg_000.off")
    vertices, faces = mesh.vertices, mesh.faces
    for _ in range(2):
        vertices, faces = trimesh.remesh.subdivide(vertices, faces)
    big = store.put_mesh(build_mesh(vertices, faces))
    kwargs = basis(store, big, 120) | {"plugin": "laplace-beltrami"}
    auto = job_demand("basis", kwargs | {"params": {"method": "auto"}}, DEFAULT_SIZING)
    exact = job_demand("basis", kwargs | {"params": {"method": "exact"}}, DEFAULT_SIZING)
    other = job_demand("basis", kwargs | {"plugin": "other"}, DEFAULT_SIZING)
    assert auto.vertices == exact.vertices == 110_210
    assert auto.memory_bytes < exact.memory_bytes == other.memory_bytes


def test_a_job_states_a_limit_and_memory_that_grow_with_its_mesh(request, store, faust_id, tmp_path):
    queue = rq_queue(request, store, JobSizing(timeout_floor_s=1, timeout_factor=100))
    try:
        from rq.job import Job

        from curvefm.workers.connection import SERIALIZER

        small, large = (queue.submit("basis", basis(store, faust_id, k)) for k in (20, 200))
        rq_small, rq_large = (Job.fetch(j.id, queue.connection, serializer=SERIALIZER) for j in (small, large))
        assert rq_small.meta["demand"]["vertices"] == 6890
        assert rq_small.timeout < rq_large.timeout
        assert rq_small.meta["demand"]["memory_bytes"] < rq_large.meta["demand"]["memory_bytes"]
        assert rq_large.timeout == job_demand("basis", basis(store, faust_id, 200), queue.sizing).timeout_s
    finally:
        queue.close()


def test_a_worker_refuses_a_job_over_its_budget_and_then_the_queue_refuses_it(request, store, faust_id):
    queue = rq_queue(request, store)
    try:
        waiting = queue.submit("basis", basis(store, faust_id, 20))  # no worker yet: it waits for one
        start_worker(request, store, "small", CURVEFM_WORKER_MEMORY=SMALL_BUDGET)
        refused = wait(queue, waiting.id)

        assert refused.state == "failed" and refused.error.kind == "too_large", refused
        assert "0.1 GB" in refused.error.message and MEMORY_SETTING in refused.error.message
        assert "6,890 vertices at k = 20" in refused.error.message
        with pytest.raises(ResourceLimit) as caught:  # its one worker is known now
            queue.submit("basis", basis(store, faust_id, 20))
        assert caught.value.setting == MEMORY_SETTING
        assert "the largest budget of the 1 workers on queue" in caught.value.message
    finally:
        queue.close()


def test_the_in_process_executor_refuses_a_job_over_its_budget(store, faust_id):
    queue = EmbeddedQueue(store.root, max_workers=1, memory_budget=64 * 2**20)
    try:
        with pytest.raises(ResourceLimit) as caught:
            queue.submit("basis", basis(store, faust_id, 20))
        assert caught.value.setting == MEMORY_SETTING and "in-process executor" in caught.value.message
        assert queue.records.unended() == []
    finally:
        queue.close()


@pytest.mark.parametrize("mode", ["embedded", "redis"])
def test_a_job_past_its_time_limit_fails_as_timeout(request, store, faust_id, mode):
    if mode == "embedded":
        queue: JobQueue = EmbeddedQueue(store.root, max_workers=1, sizing=ONE_SECOND)
    else:
        start_worker(request, store, "w1")
        queue = rq_queue(request, store, ONE_SECOND)
    try:
        job = queue.submit("basis", basis(store, faust_id, SLOW_K))
        info = wait(queue, job.id)
        assert info.state == "failed" and info.error.kind == "timeout", info
        assert "time limit of 1 s for 6,890 vertices at k = 500" in info.error.message
        assert "CURVEFM_JOB_TIMEOUT_FACTOR" in info.error.message
        assert store.stored_bases(faust_id) == [], "the basis was stored"
    finally:
        queue.close()


def test_a_work_horse_killed_by_the_kernel_fails_as_killed_and_its_worker_lives_on(request, store, faust_id):
    worker = start_worker(request, store, "w1", CURVEFM_WORKER_MEMORY="20G")
    queue = rq_queue(request, store, retries=0)
    try:
        job = queue.submit("basis", basis(store, faust_id, SLOW_K))
        running = wait(queue, job.id, until=("started", "finished", "failed"))
        assert running.state == "started", running
        (horse,) = descendants(worker.pid)
        os.kill(horse, signal.SIGKILL)  # what the OOM killer does
        killed = wait(queue, job.id)

        assert killed.state == "failed" and killed.error.kind == "killed", killed
        message = killed.error.message
        assert "signal 9 (SIGKILL)" in message and "OOM killer" in message and "GB of memory" in message
        assert "budget is 20.0 GB" in message and MEMORY_SETTING in message
        assert wait(queue, queue.submit("basis", basis(store, faust_id, 20)).id).state == "finished"
    finally:
        queue.close()


def test_the_api_answers_a_job_over_every_budget_413_naming_the_budget(processes, tmp_path, shared_data):
    api = processes.api(tmp_path / "data", env={MEMORY_SETTING: SMALL_BUDGET})  # its in-process executor's budget
    shape_id = api.upload(shared_data / "faust" / "tr_reg_000.off")

    body = expect(api.client.post(f"/shapes/{shape_id}/bases", json={"k": 20}), 413, "too_large", MEMORY_SETTING)

    assert "0.1 GB" in body["detail"] and "6,890 vertices at k = 20" in body["detail"]
    assert api.client.get(f"/shapes/{shape_id}").json()["bases"] == []
