"""The review stage over HTTP against a real API process with Redis and a worker process: a private project with a
manager, two annotators, a reviewer and a viewer; members assigned, submitted, sent back with a comment, submitted
again and accepted; who may do which; the lock on submitted and accepted members; a batch run over the accepted
members; every transition in the audit log."""

from __future__ import annotations

import time

import httpx
import pytest
from support.lab import CURVE, Lab

from curvefm.access import audit_of
from curvefm.service.models import ErrorBody, MemberReview

ROLES = {"mia": "manager", "ann": "annotator", "abe": "annotator", "rita": "reviewer", "vic": "viewer"}
ANSWER = {"template_curve": "t1", "target": CURVE["target"]}


@pytest.fixture
def project(processes, tmp_path, redis_url, redis_prefix):
    processes.worker(redis_url, redis_prefix, "w1", tmp_path / "data")
    lab = Lab(processes.api(tmp_path / "data", redis_url, env={"CURVEFM_QUEUE_PREFIX": redis_prefix}))
    session = lab.new_session()
    lab.add_curve(lab.owner, session)
    collection_id = lab.new_collection(lab.owner, session)
    users = {name: lab.api.client_for(name) for name in ROLES}
    base = f"/collections/{collection_id}"
    for name, role in ROLES.items():
        lab.owner.put(f"{base}/roles/{name}", json={"role": role}).raise_for_status()
    added = lab.owner.post(f"{base}/members", json={"shapes": [lab.new_shape(), lab.new_shape()]})
    for member in added.raise_for_status().json()["members"]:
        if member["basis_job"]:
            lab.wait_job(lab.owner, member["basis_job"])
    users["mia"].post(f"{base}/assign", json={"annotators": ["ann", "abe"]}).raise_for_status()
    return lab, users, base


def refused(response: httpx.Response, status: int, *words: str) -> None:
    assert response.status_code == status, response.text
    detail = ErrorBody.model_validate(response.json()).detail
    for word in words:
        assert word in detail, detail


def submit(client: httpx.Client, base: str, member: str) -> httpx.Response:
    return client.post(f"{base}/members/{member}/submit")


def review(client: httpx.Client, base: str, member: str, decision: str, comment: str = "") -> httpx.Response:
    return client.post(f"{base}/members/{member}/review", json={"decision": decision, "comment": comment})


def state(response: httpx.Response) -> MemberReview:
    assert response.status_code == 200, response.text
    return MemberReview.model_validate(response.json())


def run_members(client: httpx.Client, base: str, body: dict) -> list[str]:
    run = client.post(f"{base}/runs", json={"converter": "nearest-neighbor", **body}).raise_for_status().json()
    deadline = time.monotonic() + 120
    while (status := client.get(f"{base}/runs/{run['id']}").json())["state"] not in ("finished", "failed"):
        assert time.monotonic() < deadline, status
        time.sleep(0.1)
    assert status["state"] == "finished", status
    return sorted(m["member"] for m in status["members"] if not m["carried"])


def test_submit_request_changes_resubmit_accept_and_run_the_accepted(project):
    lab, users, base = project
    ann, abe, rita, mia = users["ann"], users["abe"], users["rita"], users["mia"]
    # m1 came with the session's curve (ann's), m2 is abe's, m3 ann's
    refused(submit(ann, base, "m3"), 409, "t1", "unanswered")
    refused(submit(ann, base, "m2"), 403, "not assigned to you")
    refused(submit(rita, base, "m1"), 403)
    refused(review(rita, base, "m1", "accept"), 409, "open")

    submitted = state(submit(ann, base, "m1"))
    assert (submitted.state, submitted.submitted_by) == ("submitted", "ann") and submitted.submitted_at
    m1_session = lab.owner.get(base).json()["members"][0]["session"]
    refused(ann.post(f"{base}/members/m1/curves", json=ANSWER), 409, "submitted")
    refused(ann.post(f"/sessions/{m1_session}/curves", json=CURVE), 409, "submitted")
    refused(lab.owner.post(f"/sessions/{m1_session}/curves", json=CURVE), 409, "submitted")  # the owner too
    refused(review(ann, base, "m1", "accept"), 403, "reviewer")
    refused(review(users["vic"], base, "m1", "accept"), 403, "reviewer")

    sent_back = state(review(rita, base, "m1", "request_changes", "t1 ends on the wrong ear"))
    assert (sent_back.state, sent_back.reviewed_by, sent_back.comment) == (
        "changes_requested",
        "rita",
        "t1 ends on the wrong ear",
    )
    assert ann.post(f"{base}/members/m1/curves", json=ANSWER).status_code == 201  # unlocked again
    assert state(submit(ann, base, "m1")).state == "submitted"
    accepted = state(review(rita, base, "m1", "accept"))
    assert (accepted.state, accepted.reviewed_by, accepted.submitted_by) == ("accepted", "rita", "ann")
    refused(submit(ann, base, "m1"), 409, "accepted")
    refused(ann.post(f"{base}/members/m1/curves", json=ANSWER), 409, "accepted")

    assert abe.post(f"{base}/members/m2/curves", json=ANSWER).status_code == 201
    state(submit(abe, base, "m2"))
    assert state(review(mia, base, "m2", "accept")).reviewed_by == "mia"  # managers review too
    assert ann.post(f"{base}/members/m3/curves", json=ANSWER).status_code == 201
    state(submit(ann, base, "m3"))  # submitted, not accepted

    view = users["vic"].get(base).raise_for_status().json()
    states = {m: r["state"] for m, r in view["reviews"].items()}
    assert states == {"m1": "accepted", "m2": "accepted", "m3": "submitted"}
    listed = users["vic"].get(f"{base}/reviews").raise_for_status().json()
    assert [(r["member"], r["state"], r["submitted_by"]) for r in listed] == [
        ("m1", "accepted", "ann"),
        ("m2", "accepted", "abe"),
        ("m3", "submitted", "ann"),
    ]
    assert [(w["member"], w["review"]) for w in ann.get("/me/work").json()] == [("m1", "accepted"), ("m3", "submitted")]
    progress = mia.get(f"{base}/assignments").json()["members"]
    assert [p["review"] for p in progress] == ["accepted", "accepted", "submitted"]
    refused(lab.other.get(f"{base}/reviews"), 404)
    refused(lab.other.post(f"{base}/members/m3/review", json={"decision": "accept"}), 404)

    assert run_members(mia, base, {"only_accepted": True}) == ["m1", "m2"]
    state(review(rita, base, "m2", "request_changes", "redo"))  # reopens an accepted member
    assert abe.post(f"{base}/members/m2/curves", json=ANSWER).status_code == 201
    assert run_members(mia, base, {"only_accepted": True, "members": ["m2", "m1"]}) == ["m1"]
    refused(mia.post(f"{base}/runs", json={"only_accepted": True, "members": ["m3"]}), 409, "accepted")

    events = [e for e in audit_of(lab.api.data_dir).read(limit=1000) if e["target"] == base.split("/")[-1]]
    moves = [(e["action"], e["user"], e["detail"]["member"], e["detail"]["to"]) for e in events if "to" in e["detail"]]
    assert moves[:4] == [
        ("collection.submit", "ann", "m1", "submitted"),
        ("collection.review", "rita", "m1", "changes_requested"),
        ("collection.submit", "ann", "m1", "submitted"),
        ("collection.review", "rita", "m1", "accepted"),
    ]
    assert events[[e["action"] for e in events].index("collection.review")]["detail"]["comment"].startswith("t1")


def test_bad_review_requests_are_refused_with_4xx(project):
    lab, users, base = project
    assert users["rita"].post(f"{base}/members/m1/review", json={"decision": "maybe"}).status_code == 422
    assert users["rita"].post(f"{base}/members/m1/review", json={"decision": "accept", "x": 1}).status_code == 422
    refused(review(users["rita"], base, "m9", "accept"), 404, "m9")
    refused(submit(lab.owner, base, "m9"), 404, "m9")
    refused(review(users["rita"], "/collections/nope", "m1", "accept"), 404)


def test_ask_for_further_annotations_of_many_members_at_once(project):
    lab, users, base = project
    mia, ann, abe = users["mia"], users["ann"], users["abe"]
    # ann is the assignee of m1 and m3, abe of m2
    made = mia.post(f"{base}/annotations", json={"user": "ann"})
    assert made.status_code == 201, made.text
    assert [(a["member"], a["annotator"], a["further"]) for a in made.json()] == [("m2", "ann", True)]
    assert mia.post(f"{base}/annotations", json={"user": "ann"}).json() == []  # all annotated by ann already
    chosen = mia.post(f"{base}/annotations", json={"user": "abe", "members": ["m3", "m2", "m3"]})
    assert [a["member"] for a in chosen.raise_for_status().json()] == ["m3"]  # m2 is abe's own, m3 once
    listed = abe.get(f"{base}/annotations").raise_for_status().json()
    assert [(a["member"], a["annotator"]) for a in listed if a["further"]] == [("m2", "ann"), ("m3", "abe")]
    assert ann.post(f"{base}/members/m2/curves", params={"annotator": "ann"}, json=ANSWER).status_code == 201
    work = ann.get("/me/work").raise_for_status().json()  # not done first: m3, then m1 and the further m2
    assert [(w["member"], w["further"], w["done"]) for w in work] == [
        ("m3", False, False),
        ("m1", False, True),
        ("m2", True, True),
    ]
    assert work[2]["session"] == made.json()[0]["session"] and work[2]["review"] == "open"

    refused(mia.post(f"{base}/annotations", json={"user": "abe", "members": ["m1"] * 4}), 400, "at most 3", "count")
    refused(mia.post(f"{base}/annotations", json={"user": "abe", "members": ["m9"]}), 404, "m9")
    refused(mia.post(f"{base}/annotations", json={"user": "zed"}), 404, "zed")
    refused(mia.post(f"{base}/annotations", json={"user": "vic"}), 409)  # a viewer may not answer
    refused(ann.post(f"{base}/annotations", json={"user": "abe"}), 403)
    refused(lab.other.post(f"{base}/annotations", json={"user": "abe"}), 404)
    assert mia.post(f"{base}/annotations", json={"user": "abe", "x": 1}).status_code == 422
    events = [e for e in audit_of(lab.api.data_dir).read(limit=1000) if e["action"] == "collection.annotate"]
    assert [(e["user"], e["detail"]["member"], e["detail"]["user"]) for e in events] == [
        ("mia", "m2", "ann"),
        ("mia", "m3", "abe"),
    ]
