"""Sessions and curves in the database (both engines): CRUD, revision checks, the curve diff, pages, refusals."""

from __future__ import annotations

import pytest
from support.records import curve, job_row, repositories, session_record, shape_id

from curvefm.errors import Conflict, InvalidInput, LimitExceeded, NotFound, StaleRevision
from curvefm.records.common import Viewer
from curvefm.records.sessions import Sessions, UnknownSession


@pytest.fixture
def repo(db):
    repo = repositories(db)
    repo["users"].add("alice")
    repo["users"].add("bob")
    repo["alice"], repo["bob"] = repo["users"].get("alice"), repo["users"].get("bob")
    repo["a"], repo["b"] = shape_id(), shape_id()
    repo["shapes"].add(repo["a"], 100, repo["alice"].id)
    repo["shapes"].add(repo["b"], 200, repo["alice"].id)
    return repo


def test_create_read_write_delete(repo):
    sessions: Sessions = repo["sessions"]
    record = session_record(repo["a"], repo["b"], owner="alice", curves=[curve("c1"), curve("c2", n=50)])
    sessions.create(record)
    assert sessions.exists(record.id) and not sessions.exists("nope") and not sessions.exists("../x")
    assert sessions.read(record.id) == record
    with pytest.raises(Conflict):
        sessions.create(record)
    assert sessions.read_changed(record.id, record.revision) is None
    written = sessions.write(record.model_copy(update={"sharing": "read", "name": "renamed"}))
    assert written.revision == record.revision + 1 and written.updated_at >= record.updated_at
    assert sessions.read(record.id) == written
    assert sessions.read_changed(record.id, record.revision) == written
    job = job_row(owner="alice")
    repo["jobs"].create(job)
    sessions.add_job(record.id, job.id)
    assert sessions.jobs(record.id) == [job.id]
    assert sessions.delete(record.id) == [job.id]
    assert repo["jobs"].load(job.id).session_id is None  # the job's record stays; its results are the caller's
    with pytest.raises(UnknownSession):
        sessions.read(record.id)
    with pytest.raises(UnknownSession):
        sessions.delete(record.id)


def test_a_stale_write_is_refused(repo):
    sessions = repo["sessions"]
    record = session_record(repo["a"], repo["b"], owner="alice")
    sessions.create(record)
    first = sessions.write(record.model_copy(update={"curves": [curve("c1")], "next_curve": 2}), base=record)
    with pytest.raises(StaleRevision):  # a second edit made from the same revision loses, it does not overwrite
        sessions.write(record.model_copy(update={"curves": [curve("c9")], "next_curve": 10}), base=record)
    assert sessions.read(record.id) == first


def test_curve_edits_write_what_changed(repo):
    sessions = repo["sessions"]
    record = session_record(repo["a"], repo["b"], curves=[curve("c1"), curve("c2"), curve("c3")])
    sessions.create(record)
    steps = [
        lambda cs: [*cs, curve("c4", n=7)],  # added last
        lambda cs: [curve("c5"), *cs],  # added first: every other curve moves
        lambda cs: [c if c.id != "c2" else curve("c2", n=11) for c in cs],  # replaced in place
        lambda cs: [c for c in cs if c.id != "c3"],  # removed
        lambda cs: list(reversed(cs)),  # reordered
    ]
    current = sessions.read(record.id)
    for step in steps:
        edited = current.model_copy(update={"curves": step(list(current.curves))})
        current = sessions.write(edited, base=current)
        assert sessions.read(record.id) == current
    assert [c.id for c in current.curves] == ["c4", "c2", "c1", "c5"]
    assert len(sessions.read(record.id).curves[1].path_source) == 11


def test_refusals(repo):
    sessions = repo["sessions"]
    with pytest.raises(NotFound):
        sessions.create(session_record(repo["a"], shape_id()))  # a shape that is not stored
    with pytest.raises(InvalidInput):
        sessions.create(session_record(repo["a"], repo["b"], session_id="bad id"))
    with pytest.raises(NotFound):
        sessions.create(session_record(repo["a"], repo["b"], owner="nobody"))
    small = Sessions(sessions.db, max_curves=2)
    with pytest.raises(LimitExceeded):
        small.create(session_record(repo["a"], repo["b"], curves=[curve("c1"), curve("c2"), curve("c3")]))
    with pytest.raises(LimitExceeded):
        Sessions(sessions.db, max_curve_bytes=40).create(session_record(repo["a"], repo["b"], curves=[curve("c1", 9)]))
    with pytest.raises(UnknownSession):
        sessions.write(session_record(repo["a"], repo["b"]))


def test_pages_filter_by_permission_and_continue(repo):
    sessions = repo["sessions"]
    alice, bob = repo["alice"], repo["bob"]
    made = {}
    for i in range(12):
        owner = "alice" if i % 3 else "bob"
        sharing = "read" if i % 4 == 0 else "private"
        record = session_record(repo["a"], repo["b"], owner=owner, sharing=sharing, curves=[curve("c1")] * 0)
        record = record.model_copy(update={"updated_at": 1000.0 + i})
        sessions.create(record)
        made[record.id] = record
    everything = sessions.page(Viewer(None, admin=True), limit=5)
    assert everything.total == 12 and len(everything.items) == 5
    assert [s.updated_at for s in everything.items] == [1011.0, 1010.0, 1009.0, 1008.0, 1007.0]
    seen, cursor = [], None
    while True:
        page = sessions.page(Viewer(bob.id), limit=2, cursor=cursor)
        seen += page.items
        cursor = page.next_cursor
        if cursor is None:
            break
    expected = {i for i, r in made.items() if r.owner == "bob" or r.sharing != "private"}
    assert {s.id for s in seen} == expected and page.total == len(expected)
    assert len(seen) == len(expected)
    mine = sessions.page(Viewer(alice.id), owner=alice.id, limit=50)
    assert {s.id for s in mine.items} == {i for i, r in made.items() if r.owner == "alice"}
    by_offset = sessions.page(Viewer(None, admin=True), limit=5, offset=10)
    assert len(by_offset.items) == 2 and by_offset.next_cursor is None
    assert sessions.page(Viewer(None, admin=True), shape=shape_id()).total == 0
    assert sessions.page(Viewer(None, admin=True), shape=repo["b"]).total == 12
    with pytest.raises(InvalidInput):
        sessions.page(Viewer(None, admin=True), cursor="garbage!")
    with pytest.raises(InvalidInput):
        sessions.page(Viewer(None, admin=True), limit=0)
