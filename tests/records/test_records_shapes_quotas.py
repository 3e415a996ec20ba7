"""Shapes' ownership and quotas as queries (both engines)."""

from __future__ import annotations

import threading

import pytest
from support.records import collection_record, curve, job_row, repositories, session_record, shape_id

from curvefm.collection.record import Member
from curvefm.errors import Conflict, LimitExceeded, NotFound, ResourceLimit, TooMany
from curvefm.records.common import Viewer
from curvefm.records.sessions import Sessions
from curvefm.records.usage import Limits, Quotas


@pytest.fixture
def repo(db):
    repo = repositories(db)
    for name in ("alice", "bob"):
        repo["users"].add(name)
        repo[name] = repo["users"].get(name)
    repo["users"].add("root", admin=True)
    repo["root"] = repo["users"].get("root")
    return repo


def test_uploaders_and_the_first_is_charged(repo):
    shapes, alice, bob = repo["shapes"], repo["alice"], repo["bob"]
    shape = shape_id()
    assert shapes.add(shape, 1000, alice.id) is True
    assert shapes.add(shape, 1000, alice.id) is False
    assert shapes.add(shape, 1000, bob.id) is True
    assert shapes.uploaders(shape) == ["alice", "bob"]
    quotas = Quotas(shapes.db, Limits())
    assert quotas.usage(alice.id).shape_bytes == 1000 and quotas.usage(bob.id).shape_bytes == 0


def test_a_shape_in_use_cannot_be_deleted(repo):
    shapes, sessions, collections, alice, bob = (repo[k] for k in ("shapes", "sessions", "collections", "alice", "bob"))
    a, b, t = shape_id(), shape_id(), shape_id()
    for shape in (a, b, t):
        shapes.add(shape, 10, alice.id)
    record = session_record(a, b, owner="alice")
    sessions.create(record)
    collections.create(collection_record(t, owner="alice"))
    with pytest.raises(Conflict, match="1 private record"):
        shapes.delete(a, Viewer(bob.id))
    with pytest.raises(Conflict, match="collection"):  # the old store checked sessions only
        shapes.delete(t, Viewer(alice.id))
    sessions.delete(record.id)
    shapes.delete(a, Viewer(alice.id))
    assert not shapes.exists(a) and shapes.uploaders(a) == []
    with pytest.raises(NotFound):
        shapes.delete(a, Viewer(alice.id))


def test_quotas_count_in_the_admitting_transaction(repo):
    shapes, sessions, collections, jobs, alice, root = (
        repo[k] for k in ("shapes", "sessions", "collections", "jobs", "alice", "root")
    )
    quotas = Quotas(shapes.db, Limits(bytes=1000, sessions=2, jobs=1))
    a, b = shape_id(), shape_id()
    with quotas.admit(alice, "shapes", incoming_bytes=600) as conn:
        shapes.add(a, 600, alice.id, conn)
    with pytest.raises(ResourceLimit) as too_big:
        with quotas.admit(alice, "shapes", incoming_bytes=600) as conn:
            shapes.add(b, 600, alice.id, conn)
    assert too_big.value.setting == "CURVEFM_QUOTA_BYTES"
    with quotas.admit(root, "shapes", incoming_bytes=10**9) as conn:  # admins are exempt
        shapes.add(b, 10**9, root.id, conn)
    # member sessions of a collection count (the old ledger let collections bypass the quota)
    collection = collection_record(a, owner="alice")
    collections.create(collection)
    member_session = session_record(a, b, owner="alice")
    collections.add_members(collection.id, 0, [(Member(id="m1", shape=b, session=member_session.id), member_session)])
    with quotas.admit(alice, "sessions") as conn:
        sessions.create(session_record(a, b, owner="alice"), conn)
    with pytest.raises(TooMany):
        with quotas.admit(alice, "sessions") as conn:
            sessions.create(session_record(a, b, owner="alice"), conn)
    # a block that fails charges nothing: what it made is undone with it
    with pytest.raises(RuntimeError):
        with quotas.admit(alice, "jobs") as conn:
            jobs.create(job_row(owner="alice"), conn)
            raise RuntimeError("the queue refused it")
    assert quotas.usage(alice.id).active_jobs == 0
    with quotas.admit(alice, "jobs") as conn:
        job = job_row(owner="alice")
        jobs.create(job, conn)
    with pytest.raises(TooMany):
        with quotas.admit(alice, "jobs"):
            pass
    jobs.update(job.id, state="finished", ended_at=1.0, result_bytes=300)
    used = quotas.usage(alice.id)
    assert (used.sessions, used.active_jobs, used.bytes) == (2, 0, 900)


def test_parallel_admissions_never_pass_the_quota_together(repo):
    shapes, sessions, alice = repo["shapes"], repo["sessions"], repo["alice"]
    quotas = Quotas(shapes.db, Limits(sessions=3))
    a, b = shape_id(), shape_id()
    shapes.add(a, 1, alice.id)
    shapes.add(b, 1, alice.id)
    admitted, refused = [], []

    def one() -> None:
        try:
            with quotas.admit(alice, "sessions") as conn:
                record = session_record(a, b, owner="alice")
                sessions.create(record, conn)
            admitted.append(record.id)
        except TooMany:
            refused.append(1)

    threads = [threading.Thread(target=one) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(admitted) == 3 and len(refused) == 5
    assert quotas.usage(alice.id).sessions == 3


def test_a_sessions_size_is_capped_and_counts_in_its_owners_byte_quota(repo):
    shapes, alice = repo["shapes"], repo["alice"]
    sessions = Sessions(shapes.db, max_session_bytes=1000)
    a, b = shape_id(), shape_id()
    shapes.add(a, 100, alice.id)
    shapes.add(b, 100, alice.id)
    record = session_record(a, b, owner="alice", curves=[curve("c1", 50)])  # 4 x (50 + 50 + 2 + 2) bytes
    sessions.create(record)
    quotas = Quotas(shapes.db, Limits(bytes=200 + 416 + 10))
    used = quotas.usage(alice.id)
    assert (used.session_bytes, used.bytes) == (416, 200 + 416)

    grown = record.model_copy(update={"curves": [*record.curves, curve("c2", 100)]})  # 816 bytes more
    with pytest.raises(LimitExceeded) as refused:
        sessions.write(grown)
    assert refused.value.setting == "CURVEFM_MAX_SESSION_BYTES"
    assert "would store 1232 bytes" in refused.value.message and "limit of 1000 bytes" in refused.value.message
    assert sessions.read(record.id) == record and quotas.usage(alice.id).session_bytes == 416  # nothing stored
    with pytest.raises(ResourceLimit, match="416 of them your sessions' curves"):  # the records fill the quota
        with quotas.admit(alice, "shapes", incoming_bytes=100):
            pass

    sessions.write(record.model_copy(update={"curves": []}))
    assert quotas.usage(alice.id).session_bytes == 0
    with quotas.admit(alice, "shapes", incoming_bytes=100):
        pass
