"""Review comments over HTTP against a real API process: a private project with a manager, two annotators, a
reviewer and a viewer; a reviewer pins comments to vertices of the template and of the member, the member's
annotator replies and resolves, who may do which, bad requests answered with the published error schema, the
configured limits named, and every comment, resolution and deletion in the audit log."""

from __future__ import annotations

import httpx
import pytest
from support.lab import Lab

from curvefm.access import audit_of
from curvefm.service.models import ErrorBody, ReviewCommentView

ROLES = {"mia": "manager", "ann": "annotator", "abe": "annotator", "rita": "reviewer", "vic": "viewer"}
LIMITS = {"CURVEFM_MAX_COMMENT_CHARS": "40", "CURVEFM_MAX_REVIEW_COMMENTS": "3"}


@pytest.fixture
def project(processes, tmp_path):
    lab = Lab(processes.api(tmp_path / "data", env=LIMITS))
    session = lab.new_session()
    lab.add_curve(lab.owner, session)
    collection_id = lab.new_collection(lab.owner, session)
    users = {name: lab.api.client_for(name) for name in ROLES}
    base = f"/collections/{collection_id}"
    for name, role in ROLES.items():
        lab.owner.put(f"{base}/roles/{name}", json={"role": role}).raise_for_status()
    lab.owner.post(f"{base}/members", json={"shapes": [lab.new_shape()]}).raise_for_status()
    users["mia"].put(f"{base}/members/m1/assignee", json={"user": "ann"}).raise_for_status()
    return lab, users, base


def refused(response: httpx.Response, status: int, *words: str) -> ErrorBody:
    assert response.status_code == status, response.text
    body = ErrorBody.model_validate(response.json())
    for word in words:
        assert word in body.detail, body.detail
    return body


def comment(client: httpx.Client, base: str, member: str, **body) -> httpx.Response:
    return client.post(f"{base}/members/{member}/comments", json=body)


def made(response: httpx.Response) -> ReviewCommentView:
    assert response.status_code == 201, response.text
    return ReviewCommentView.model_validate(response.json())


def resolve(client: httpx.Client, base: str, comment_id: str, resolved: bool) -> httpx.Response:
    return client.patch(f"{base}/members/m1/comments/{comment_id}", json={"resolved": resolved})


def test_a_reviewer_pins_comments_and_the_annotator_replies_and_resolves(project):
    lab, users, base = project
    rita, ann, abe, vic, mia = (users[name] for name in ("rita", "ann", "abe", "vic", "mia"))
    low = made(comment(rita, base, "m1", text="t1 ends too low", side="source", vertex=60))
    assert (low.member, low.side, low.vertex, low.author, low.reply_to, low.resolved_by) == (
        "m1",
        "source",
        60,
        "rita",
        None,
        None,
    )
    ear = made(comment(rita, base, "m1", text="wrong ear", side="target", vertex=5))
    refused(comment(ann, base, "m1", text="hm", side="target", vertex=5), 403, "reviewer")
    refused(comment(vic, base, "m1", text="hm", reply_to=low.id), 403, "annotator")
    refused(comment(abe, base, "m1", text="hm", reply_to=low.id), 403)  # m1 is ann's, not abe's
    reply = made(comment(ann, base, "m1", text="moved it up", reply_to=low.id))
    assert (reply.side, reply.vertex, reply.reply_to, reply.author) == ("source", 60, low.id, "ann")

    listed = [ReviewCommentView.model_validate(c) for c in vic.get(f"{base}/members/m1/comments").json()]
    assert [(c.id, c.text) for c in listed] == [(low.id, low.text), (ear.id, ear.text), (reply.id, reply.text)]
    assert vic.get(f"{base}/members/m2/comments").json() == []
    refused(lab.other.get(f"{base}/members/m1/comments"), 404)
    refused(vic.get(f"{base}/members/m9/comments"), 404, "m9")

    refused(resolve(vic, base, low.id, True), 403)
    resolved = resolve(ann, base, reply.id, True).raise_for_status().json()  # a reply resolves its thread
    assert (resolved["id"], resolved["resolved_by"]) == (low.id, "ann")
    assert resolve(mia, base, low.id, False).raise_for_status().json()["resolved_by"] is None

    refused(ann.delete(f"{base}/members/m1/comments/{ear.id}"), 403, "author")
    assert rita.delete(f"{base}/members/m1/comments/{low.id}").status_code == 204
    assert [c["id"] for c in ann.get(f"{base}/members/m1/comments").json()] == [ear.id]  # its reply went too

    events = [e for e in audit_of(lab.api.data_dir).read(limit=1000) if e["action"].startswith("collection.comment")]
    assert [(e["action"], e["user"], e["detail"]["comment"]) for e in events] == [
        ("collection.comment", "rita", low.id),
        ("collection.comment", "rita", ear.id),
        ("collection.comment", "ann", reply.id),
        ("collection.comment_resolve", "ann", low.id),
        ("collection.comment_resolve", "mia", low.id),
        ("collection.comment_delete", "rita", low.id),
    ]
    assert (events[0]["detail"]["side"], events[0]["detail"]["vertex"]) == ("source", 60)


def test_bad_comments_are_refused_naming_what_is_wrong_and_the_limits(project):
    lab, users, base = project
    rita = users["rita"]
    n_vertices = lab.meshes[lab.shapes[0]].n_file_vertices
    refused(comment(rita, base, "m2", text="x", side="source", vertex=n_vertices), 409, f"{n_vertices} vertices")
    for bad in (
        {"text": "x", "side": "source", "vertex": -1},
        {"text": "x", "side": "left", "vertex": 1},
        {"text": "x", "side": "source"},
        {"text": "x", "side": "source", "vertex": 1, "reply_to": "rc1"},
        {"text": " \n ", "side": "source", "vertex": 1},
        {"text": "a\x00b", "side": "source", "vertex": 1},
        {"text": "x", "side": "source", "vertex": 1, "colour": "red"},
    ):
        assert refused(comment(rita, base, "m2", **bad), 422).fields, bad
    long = "a" * 41
    too_long = refused(comment(rita, base, "m2", text=long, side="target", vertex=1), 422, "max_comment_chars")
    assert too_long.limit == "CURVEFM_MAX_COMMENT_CHARS" and long not in too_long.detail
    refused(comment(rita, base, "m9", text="x", side="target", vertex=1), 404, "m9")
    refused(comment(rita, base, "m2", text="x", reply_to="rc0000"), 404, "rc0000")
    refused(rita.patch(f"{base}/members/m2/comments/rc0000", json={"resolved": "maybe"}), 422)
    for vertex in range(3):
        made(comment(rita, base, "m2", text="x", side="target", vertex=vertex))
    full = refused(comment(rita, base, "m2", text="x", side="target", vertex=4), 413, "4 comments on member m2")
    assert full.limit == "CURVEFM_MAX_REVIEW_COMMENTS"


def test_the_annotator_of_a_further_annotation_replies_and_resolves_as_the_assignee_does(project):
    lab, users, base = project
    rita, abe, mia = users["rita"], users["abe"], users["mia"]
    low = made(comment(rita, base, "m1", text="t1 ends too low", side="source", vertex=60))
    refused(comment(abe, base, "m1", text="hm", reply_to=low.id), 403, "further annotation")
    mia.post(f"{base}/members/m1/annotations", json={"user": "abe"}).raise_for_status()
    reply = made(comment(abe, base, "m1", text="mine too", reply_to=low.id))
    assert (reply.author, reply.reply_to) == ("abe", low.id)
    assert resolve(abe, base, reply.id, True).raise_for_status().json()["resolved_by"] == "abe"
    refused(comment(abe, base, "m1", text="and here", side="target", vertex=5), 403, "reviewer")
    refused(comment(abe, base, "m2", text="hm", reply_to=low.id), 403)  # abe annotates m1 only
    lab.owner.put(f"{base}/roles/abe", json={"role": "viewer"}).raise_for_status()  # no longer answers
    refused(resolve(abe, base, low.id, False), 403)
