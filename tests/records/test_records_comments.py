"""Review comments in the database (both engines): threads pinned to a vertex, replies at their thread's vertex,
resolving a thread from any of its comments, the per-member limit counted as comments are added, deletion with the
replies, and the comments going with their collection."""

from __future__ import annotations

import pytest
from support.records import collection_record, repositories, shape_id

from curvefm.errors import LimitExceeded, NotFound
from curvefm.records.comments import NewComment, ReviewComments

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
    repo["cid"], repo["comments"] = record.id, ReviewComments(db)
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
