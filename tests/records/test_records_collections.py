"""Collections in the database (both engines): members with their sessions, runs, cascades, revision checks."""

from __future__ import annotations

import pytest
from support.records import collection_record, curve, job_row, repositories, session_record, shape_id

from curvefm.collection.record import Member, Run, RunMember
from curvefm.errors import Conflict, NotFound
from curvefm.records.collections import UnknownCollection
from curvefm.records.common import Viewer
from curvefm.records.sessions import StaleRevision, UnknownSession


@pytest.fixture
def repo(db):
    repo = repositories(db)
    repo["users"].add("alice")
    repo["alice"] = repo["users"].get("alice")
    repo["template"], repo["m1"], repo["m2"] = shape_id(), shape_id(), shape_id()
    for shape in (repo["template"], repo["m1"], repo["m2"]):
        repo["shapes"].add(shape, 10, repo["alice"].id)
    return repo


def _with_members(repo, n: int = 2):
    collections = repo["collections"]
    record = collection_record(repo["template"], owner="alice")
    collections.create(record)
    added = []
    for i, shape in enumerate([repo["m1"], repo["m2"]][:n], 1):
        session = session_record(repo["template"], shape, owner="alice", curves=[curve("c1", template_curve="t1")])
        added.append((Member(id=f"m{i}", shape=shape, session=session.id), session))
    return collections.add_members(record.id, record.revision, added), [s for _, s in added]


def test_create_members_runs_and_read_back(repo):
    collections, jobs = repo["collections"], repo["jobs"]
    record, sessions = _with_members(repo)
    assert record.revision == 1 and [m.id for m in record.members] == ["m1", "m2"] and record.next_member == 3
    job1, job2 = job_row(owner="alice"), job_row(owner="alice")
    jobs.create(job1)
    jobs.create(job2)
    run = Run(
        id="r1",
        converter="zoomout",
        params={"k_final": 60},
        created_at=1.0,
        members={"m1": RunMember(job=job1.id, revision=1), "m2": RunMember(job=job2.id, revision=0, carried=True)},
    )
    basis = job_row(owner="alice", kind="basis")
    jobs.create(basis)
    members = [record.members[0].model_copy(update={"basis_job": basis.id}), record.members[1]]
    changed = record.model_copy(update={"runs": [run], "next_run": 2, "members": members})
    written = collections.write(changed)
    assert collections.read(record.id) == written
    with pytest.raises(StaleRevision):
        collections.write(changed)
    assert collections.page(Viewer(repo["alice"].id)).items[0].n_members == 2
    # an expired job leaves the run readable, naming the job it had
    jobs.update(job1.id, state="finished", ended_at=1.0)
    assert jobs.expire(ended_before=2.0) == [job1.id]
    again = collections.read(record.id)
    assert again.runs[0].members["m1"].job == job1.id
    assert collections.expired_jobs(record.id) == {("r1", "m1"): job1.id}


def test_adding_members_is_all_or_nothing(repo):
    collections, sessions = repo["collections"], repo["sessions"]
    record = collection_record(repo["template"], owner="alice")
    collections.create(record)
    good = session_record(repo["template"], repo["m1"], owner="alice")
    bad = session_record(repo["template"], shape_id(), owner="alice")  # its shape is not stored
    with pytest.raises(NotFound):
        collections.add_members(
            record.id,
            record.revision,
            [
                (Member(id="m1", shape=repo["m1"], session=good.id), good),
                (Member(id="m2", shape="x", session=bad.id), bad),
            ],
        )
    assert not sessions.exists(good.id) and collections.read(record.id).members == []
    with pytest.raises(StaleRevision):
        collections.add_members(record.id, record.revision + 5, [])


def test_deleting_a_member_session_keeps_the_collection(repo):
    collections, sessions = repo["collections"], repo["sessions"]
    record, member_sessions = _with_members(repo)
    sessions.delete(member_sessions[0].id)
    left = collections.read(record.id)  # the old store answered 404 for the whole collection here
    assert [m.id for m in left.members] == ["m2"] and left.revision == record.revision + 1
    with pytest.raises(StaleRevision):  # a copy read before the member left cannot bring it back
        collections.write(record)
    with pytest.raises(Conflict):
        collections.write(left.model_copy(update={"members": record.members}))


def test_deleting_the_collection_deletes_its_member_sessions(repo):
    collections, sessions, jobs = repo["collections"], repo["sessions"], repo["jobs"]
    record, member_sessions = _with_members(repo)
    job = job_row(owner="alice")
    jobs.create(job)
    sessions.add_job(member_sessions[1].id, job.id)
    assert collections.delete(record.id) == [job.id]
    for session in member_sessions:
        with pytest.raises(UnknownSession):
            sessions.read(session.id)
    with pytest.raises(UnknownCollection):
        collections.read(record.id)
    with pytest.raises(UnknownCollection):
        collections.delete(record.id)


def test_create_refuses_a_duplicate_and_an_unknown_template(repo):
    collections = repo["collections"]
    record = collection_record(repo["template"])
    collections.create(record)
    with pytest.raises(Conflict):
        collections.create(record)
    with pytest.raises(NotFound):
        collections.create(collection_record(shape_id()))


def test_pages_of_collections(repo):
    collections, users = repo["collections"], repo["users"]
    users.add("bob")
    bob = users.get("bob")
    for i in range(7):
        record = collection_record(
            repo["template"], owner="alice" if i % 2 else "bob", sharing="read" if i == 0 else "private"
        )
        collections.create(record.model_copy(update={"updated_at": 100.0 + i}))
    assert collections.page(Viewer(None, admin=True), limit=3).total == 7
    seen, cursor = [], None
    while True:
        page = collections.page(Viewer(repo["alice"].id), limit=2, cursor=cursor)
        seen += [c.updated_at for c in page.items]
        if (cursor := page.next_cursor) is None:
            break
    assert seen == [105.0, 103.0, 101.0, 100.0]  # alice's three, and bob's shared one
    assert collections.page(Viewer(bob.id), owner=bob.id).total == 4
    assert [c.updated_at for c in collections.page(Viewer(bob.id), limit=2, offset=2).items] == [102.0, 100.0]
    assert len(collections.list()) == 7
