"""Job records in the database (both engines): the operations of the old JobRecords."""

from __future__ import annotations

import pytest
from support.records import job_row, repositories, session_record, shape_id

from curvefm.errors import Conflict, InvalidInput, NotFound
from curvefm.records.common import Viewer
from curvefm.records.jobs import Jobs
from curvefm.records.users import Users


def test_create_load_update_and_the_end_rule(db):
    Users(db).add("alice")
    jobs = Jobs(db)
    job = job_row(owner="alice", dedupe_key="refine:abc")
    jobs.create(job)
    with pytest.raises(Conflict):
        jobs.create(job)
    assert jobs.load(job.id) == job
    assert jobs.load("missing") is None and jobs.load("../../etc") is None
    assert jobs.active("refine:abc").id == job.id
    started = jobs.update(job.id, state="started", started_at=5.0, worker="w1")
    assert started.state == "started" and started.worker == "w1"
    assert [j.id for j in jobs.unended()] == [job.id]

    class Failure:
        kind, message = "internal", "it broke"

    failed = jobs.update(job.id, state="failed", error=Failure(), ended_at=6.0)
    assert failed.error == ("internal", "it broke") and failed.ended
    assert jobs.update(job.id, progress=0.5, message="late").progress == failed.progress  # an end stays an end
    assert jobs.lose(job.id, "gone").state == "failed"
    assert jobs.update(job.id, state="finished", result={"ok": True}).state == "finished"  # to another end
    assert jobs.active("refine:abc") is None and jobs.unended() == []
    assert jobs.update("missing", state="started") is None


def test_lose_progress_expire_delete(db):
    jobs = Jobs(db)
    a, b, c = job_row(), job_row(), job_row(state="finished", ended_at=10.0)
    for job in (a, b, c):
        jobs.create(job)
    jobs.progress(a.id, 0.25, "a quarter")
    jobs.progress(a.id, 0.5, "throttled: not written")
    assert (jobs.load(a.id).progress, jobs.load(a.id).message) == (0.25, "a quarter")
    lost = jobs.lose(a.id, "Redis restarted")
    assert lost.state == "lost" and lost.message == "Redis restarted" and lost.ended_at
    assert jobs.expire(ended_before=11.0) == [c.id]
    assert jobs.load(c.id) is None and jobs.load(a.id) is not None
    jobs.delete(b.id)
    assert jobs.load(b.id) is None


def test_a_sessions_refinements_are_paged_and_filtered_in_sql(db):
    repo = repositories(db)
    for name in ("alice", "bob"):
        repo["users"].add(name)
    alice, bob = repo["users"].get("alice"), repo["users"].get("bob")
    source, target = shape_id(), shape_id()
    for shape in (source, target):
        repo["shapes"].add(shape, 10, alice.id)
    session = session_record(source, target, owner="alice", sharing="read")
    repo["sessions"].create(session)
    jobs = Jobs(db)
    made = [  # oldest first
        job_row(owner="alice", state="queued", created_at=1.0, session_id=session.id),
        job_row(owner="bob", state="finished", created_at=2.0, session_id=session.id),
        job_row(owner="bob", state="failed", created_at=3.0, session_id=session.id),
        job_row(owner="alice", state="finished", created_at=4.0, session_id=session.id),
        job_row(owner="alice", state="finished", created_at=5.0),  # of no session
    ]
    for job in made:
        jobs.create(job)

    def listed(viewer: Viewer, limit: int = 10, offset: int = 0) -> tuple[list[str], int]:
        page = jobs.of_session(session.id, viewer, limit, offset)
        return [job.id for job in page.items], page.total

    ids = [job.id for job in made]
    assert listed(Viewer(alice.id)) == ([ids[0], ids[1], ids[3]], 3)  # hers, and bob's finished one
    assert listed(Viewer(bob.id)) == ([ids[1], ids[2], ids[3]], 3)
    assert listed(Viewer(bob.id), limit=2, offset=1) == ([ids[2], ids[3]], 3)
    assert listed(Viewer(None)) == ([ids[1], ids[3]], 2)  # nobody's: the finished ones
    assert listed(Viewer(alice.id, admin=True)) == (ids[:4], 4)
    with pytest.raises(InvalidInput):
        jobs.of_session(session.id, Viewer(alice.id), limit=501)
    with pytest.raises(NotFound):  # a refinement of a session that is gone
        jobs.create(job_row(owner="alice", session_id="no-such-session"))
