"""Review states and further annotations of collection members in the database (both engines): transitions with
who and when, refusals naming where a member stands, the lock on a member's session, and further annotations'
sessions going with their member and their collection."""

from __future__ import annotations

import pytest
from support.records import collection_record, curve, repositories, session_record, shape_id

from curvefm.collection.record import Member
from curvefm.errors import Conflict, NotFound
from curvefm.records.common import Viewer
from curvefm.records.sessions import UnknownSession

FROM_OPEN = ("open", "changes_requested")


@pytest.fixture
def repo(db):
    repo = repositories(db)
    for name in ("alice", "ann", "rita"):
        repo["users"].add(name)
        repo[name] = repo["users"].get(name)
    repo["template"], repo["shape"] = shape_id(), shape_id()
    for shape in (repo["template"], repo["shape"]):
        repo["shapes"].add(shape, 10, repo["alice"].id)
    record = collection_record(repo["template"], owner="alice")
    repo["collections"].create(record)
    session = session_record(repo["template"], repo["shape"], owner="alice", curves=[curve("c1", template_curve="t1")])
    member = Member(id="m1", shape=repo["shape"], session=session.id)
    repo["record"] = repo["collections"].add_members(record.id, record.revision, [(member, session)])
    repo["session"] = session.id
    return repo


def test_a_member_is_submitted_sent_back_and_accepted_with_who_and_when(repo):
    collections, cid = repo["collections"], repo["record"].id
    assert collections.reviews(cid) == {}
    assert collections.locked_member(repo["session"]) is None
    assert collections.move_review(cid, "m1", "submitted", FROM_OPEN, repo["ann"].id) == "open"
    submitted = collections.reviews(cid)["m1"]
    assert (submitted.state, submitted.submitted_by, submitted.reviewed_by) == ("submitted", "ann", None)
    assert submitted.submitted_at is not None
    assert collections.locked_member(repo["session"]) == (cid, "m1", "submitted")
    with pytest.raises(Conflict, match="is submitted"):
        collections.move_review(cid, "m1", "submitted", FROM_OPEN, repo["ann"].id)

    collections.move_review(cid, "m1", "changes_requested", ("submitted",), repo["rita"].id, "move t1's end")
    back = collections.reviews(cid)["m1"]
    assert (back.state, back.reviewed_by, back.comment, back.submitted_by) == (
        "changes_requested",
        "rita",
        "move t1's end",
        "ann",
    )
    assert collections.locked_member(repo["session"]) is None
    collections.move_review(cid, "m1", "submitted", FROM_OPEN, repo["ann"].id)
    collections.move_review(cid, "m1", "accepted", ("submitted",), repo["rita"].id)
    accepted = collections.reviews(cid)["m1"]
    assert (accepted.state, accepted.comment) == ("accepted", "")
    assert accepted.reviewed_at >= accepted.submitted_at
    assert collections.locked_member(repo["session"]) == (cid, "m1", "accepted")
    with pytest.raises(NotFound, match="m9"):
        collections.move_review(cid, "m9", "submitted", FROM_OPEN, repo["ann"].id)


def test_a_further_annotation_is_a_session_that_goes_with_its_member(repo):
    collections, sessions, cid = repo["collections"], repo["sessions"], repo["record"].id
    further = session_record(repo["template"], repo["shape"], owner="alice")
    collections.add_annotation(cid, "m1", repo["rita"].id, further)
    with pytest.raises(Conflict, match="already"):
        collections.add_annotation(cid, "m1", repo["rita"].id, session_record(repo["template"], repo["shape"]))
    annotations = collections.annotations(cid)
    assert [(a.member_id, a.user, a.session_id, a.further) for a in annotations] == [
        ("m1", None, repo["session"], False),
        ("m1", "rita", further.id, True),
    ]
    standing = collections.annotation_standing(further.id, Viewer(repo["rita"].id))
    assert standing is not None and standing.assignee == repo["rita"].id and standing.collection_id == cid
    assert collections.annotation_standing(repo["session"], Viewer(repo["rita"].id)) is None
    in_collections = {s.id for s in sessions.page(Viewer(repo["alice"].id), in_collection=True).items}
    assert in_collections == {repo["session"], further.id}
    assert not sessions.page(Viewer(repo["alice"].id), in_collection=False).items  # the session list leaves both out
    collections.assign(cid, {"m1": repo["ann"].id})
    assert [(w.member_id, w.session_id, w.further) for w in collections.work(repo["rita"].id)] == [
        ("m1", further.id, True)
    ]
    assert [(w.session_id, w.further) for w in collections.work(repo["ann"].id)] == [(repo["session"], False)]

    collections.remove_member(cid, "m1")
    for session_id in (further.id, repo["session"]):
        with pytest.raises(UnknownSession):
            sessions.read(session_id)
    assert collections.annotations(cid) == []


def test_deleting_the_collection_deletes_further_annotations(repo):
    collections, sessions, cid = repo["collections"], repo["sessions"], repo["record"].id
    further = session_record(repo["template"], repo["shape"], owner="alice")
    collections.add_annotation(cid, "m1", repo["ann"].id, further)
    collections.move_review(cid, "m1", "submitted", FROM_OPEN, repo["ann"].id)
    collections.delete(cid)
    with pytest.raises(UnknownSession):
        sessions.read(further.id)
    assert collections.reviews(cid) == {}
