"""Review comments in the database (both engines): threads pinned to a vertex, replies at their thread's vertex,
resolving a thread from any of its comments, the per-member limit counted as comments are added, deletion with the
replies, the comments going with their collection, and the sessions that show them (a member's own and its further
annotations', with the mark the event poller compares)."""

from __future__ import annotations

from itertools import pairwise

import pytest
from support.records import collection_record, repositories, session_record, shape_id

from curvefm.collection.record import Member
from curvefm.errors import LimitExceeded, NotFound
from curvefm.records.comments import NewComment, ReviewComments
from curvefm.records.viewers import Viewers

LIMIT = 4


@pytest.fixture
def repo(db):
    repo = repositories(db)
    for name in ("alice", "ann", "rita"):
        repo["users"].add(name)
        repo[name] = repo["users"].get(name)
    template = shape_id()
    repo["shapes"].add(template, 10, repo["alice"].id)
    record = collection_record(template, owner="alice")
    repo["collections"].create(record)
    repo["cid"], repo["revision"], repo["template"] = record.id, record.revision, template
    repo["comments"] = ReviewComments(db)
    return repo


def test_a_thread_pinned_to_a_vertex_with_a_reply_resolved_and_reopened(repo):
    comments, cid, rita, ann = repo["comments"], repo["cid"], repo["rita"], repo["ann"]
    first = comments.add(cid, "m1", NewComment("t1 ends too low", "source", 7), rita.id, LIMIT)
    assert (first.side, first.vertex, first.author, first.reply_to, first.resolved_by) == (
        "source",
        7,
        "rita",
        None,
        None,
    )
    other = comments.add(cid, "m1", NewComment("and here", "target", 3), rita.id, LIMIT)
    reply = comments.add(cid, "m1", NewComment("moved it", reply_to=first.id), ann.id, LIMIT)
    assert (reply.side, reply.vertex, reply.reply_to, reply.author) == ("source", 7, first.id, "ann")
    again = comments.add(cid, "m1", NewComment("thanks", reply_to=reply.id), rita.id, LIMIT)
    assert again.reply_to == first.id  # a reply to a reply joins the same thread
    assert [c.id for c in comments.thread(cid, "m1")] == [first.id, other.id, reply.id, again.id]
    assert comments.thread(cid, "m2") == []

    resolved = comments.resolve(cid, "m1", reply.id, ann.id, True)
    assert (resolved.id, resolved.resolved_by) == (first.id, "ann") and resolved.resolved_at is not None
    assert comments.resolve(cid, "m1", first.id, rita.id, False).resolved_by is None
    with pytest.raises(LimitExceeded, match="CURVEFM_MAX_REVIEW_COMMENTS"):
        comments.add(cid, "m1", NewComment("one more", "target", 1), rita.id, LIMIT)
    with pytest.raises(NotFound, match="nope"):
        comments.add(cid, "m2", NewComment("?", reply_to="nope"), rita.id, LIMIT)
    with pytest.raises(NotFound):
        comments.resolve(cid, "m2", first.id, rita.id, True)  # another member's comment

    comments.delete(cid, "m1", first.id)
    assert [c.id for c in comments.thread(cid, "m1")] == [other.id]  # the replies went with it
    with pytest.raises(NotFound):
        comments.delete(cid, "m1", first.id)
    repo["collections"].delete(cid)
    assert comments.thread(cid, "m1") == []


def test_the_sessions_showing_a_members_comments_and_their_mark_moving_with_each_change(repo):
    comments, cid, rita, ann = repo["comments"], repo["cid"], repo["rita"], repo["ann"]
    template, shape = repo["template"], shape_id()
    repo["shapes"].add(shape, 10, repo["alice"].id)
    own = session_record(template, shape, owner="alice")
    repo["collections"].add_members(cid, repo["revision"], [(Member(id="m1", shape=shape, session=own.id), own)])
    further = session_record(template, shape, owner="alice")
    repo["collections"].add_annotation(cid, "m1", ann.id, further)
    assert comments.sessions(cid, "m1") == {own.id: own.revision, further.id: further.revision}
    assert comments.annotates(cid, "m1", ann.id) and not comments.annotates(cid, "m1", rita.id)
    assert not comments.annotates(cid, "m2", ann.id)

    viewers, both = Viewers(repo["comments"].db), [own.id, further.id]
    marks = [viewers.comment_marks(both)]
    assert marks[0] == {}  # no comments yet
    first = comments.add(cid, "m1", NewComment("here", "target", 3), rita.id, LIMIT)
    changes = [
        lambda: comments.add(cid, "m1", NewComment("moved", reply_to=first.id), ann.id, LIMIT),
        lambda: comments.resolve(cid, "m1", first.id, ann.id, True),
        lambda: comments.resolve(cid, "m1", first.id, rita.id, False),
        lambda: comments.delete(cid, "m1", first.id),
    ]
    for change in [lambda: None, *changes]:
        change()
        marks.append(viewers.comment_marks(both))
        assert marks[-1].get(own.id) == marks[-1].get(further.id)  # both sessions show the same comments
    assert all(a != b for a, b in pairwise(marks)), marks  # every change moved the mark
    assert marks[-1] == {}
