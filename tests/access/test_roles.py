"""Roles in a collection (a project) over HTTP against a real server process: a private collection with a manager,
two annotators, a reviewer and a viewer; what each may and may not do, how roles combine with the lab-wide
sharing (the higher of the two), who may grant which role, and the audit log of grants."""

from __future__ import annotations

import httpx
import pytest
from support.lab import CURVE, Lab

from curvefm.access import audit_of
from curvefm.service.models import ErrorBody

ROLES = {"mia": "manager", "ann": "annotator", "abe": "annotator", "rita": "reviewer", "vic": "viewer"}
ANSWER = {"template_curve": "t1", "target": CURVE["target"]}


class Project:
    def __init__(self, lab: Lab):
        self.lab = lab
        self.users = {name: lab.api.client_for(name) for name in ROLES}
        session = lab.new_session()
        lab.add_curve(lab.owner, session)
        self.id = lab.new_collection(lab.owner, session)
        self.base = f"/collections/{self.id}"
        for name, role in ROLES.items():
            lab.owner.put(f"{self.base}/roles/{name}", json={"role": role}).raise_for_status()

    def __getitem__(self, name: str) -> httpx.Client:
        return self.users[name]

    @property
    def member_session(self) -> str:
        return self.lab.owner.get(self.base).json()["collection"]["members"][0]["session"]


@pytest.fixture(scope="module")
def lab(module_processes, tmp_path_factory) -> Lab:
    return Lab(module_processes.api(tmp_path_factory.mktemp("roles") / "data"))


@pytest.fixture
def project(lab) -> Project:
    return Project(lab)


def refused(response, status: int = 403, *words: str) -> dict:
    assert response.status_code == status, response.text
    body = ErrorBody.model_validate(response.json())
    assert "tester" not in body.detail and "mia" not in body.detail, body  # a refusal names no one
    for word in words:
        assert word in body.detail, body
    return response.json()


def listed(client: httpx.Client, collection_id: str) -> bool:
    return collection_id in {c["id"] for c in client.get("/collections").raise_for_status().json()}


def test_the_roles_are_listed_with_the_creator_first(project):
    roles = project["vic"].get(f"{project.base}/roles").raise_for_status().json()
    assert [(r["user"], r["role"]) for r in roles] == [
        ("tester", "owner"),
        ("mia", "manager"),
        ("abe", "annotator"),
        ("ann", "annotator"),
        ("rita", "reviewer"),
        ("vic", "viewer"),
    ]
    assert roles[0]["granted_by"] is None and {r["granted_by"] for r in roles[1:]} == {"tester"}
    assert all(isinstance(r["user_id"], int) for r in roles)


def test_every_role_reads_and_an_outsider_sees_nothing(project, lab):
    for name in ROLES:
        assert project[name].get(project.base).status_code == 200, name
        assert listed(project[name], project.id), name
        assert project[name].get(f"/sessions/{project.member_session}").status_code == 200, name
    run = lab.finished_run(lab.owner, project.id)
    (job,) = [m["job"] for m in lab.owner.get(f"{project.base}/runs/{run}").json()["members"]]
    assert project["vic"].get(f"/jobs/{job}").json()["state"] == "finished"  # a member session's job
    refused(lab.other.get(f"/jobs/{job}"), 404)
    refused(lab.other.get(project.base), 404)
    refused(lab.other.get(f"{project.base}/roles"), 404)
    refused(lab.other.get(f"/sessions/{project.member_session}"), 404)
    assert not listed(lab.other, project.id)


def test_annotators_and_managers_answer_reviewers_and_viewers_may_not(project):
    for name in ("ann", "abe", "mia"):
        assert project[name].post(f"{project.base}/members/m1/curves", json=ANSWER).status_code == 201, name
    for name in ("rita", "vic"):
        refused(project[name].post(f"{project.base}/members/m1/curves", json=ANSWER), 403, "annotator")
    session = f"/sessions/{project.member_session}"
    assert project["ann"].post(f"{session}/curves", json=CURVE).status_code == 201  # the member session alike
    refused(project["vic"].post(f"{session}/curves", json=CURVE), 403)
    refused(project["ann"].patch(session, json={"sharing": "edit"}), 403)  # sharing it is its owners'


def test_only_managers_and_owners_change_members_runs_sharing_and_roles(project, lab):
    shape = lab.new_shape()
    for name in ("ann", "rita", "vic"):
        refused(project[name].post(f"{project.base}/members", json={"shapes": [shape]}), 403, "manager")
        refused(project[name].post(f"{project.base}/runs", json={"converter": "nearest-neighbor"}), 403)
        refused(project[name].patch(project.base, json={"sharing": "read"}), 403)
        refused(project[name].put(f"{project.base}/roles/oscar", json={"role": "viewer"}), 403, "manager")
        refused(project[name].delete(f"{project.base}/roles/vic"), 403)
    added = project["mia"].post(f"{project.base}/members", json={"shapes": [shape]})
    assert added.status_code == 201 and len(added.json()["members"]) == 2
    assert project["mia"].delete(f"{project.base}/members/m2").status_code == 204
    assert project["mia"].patch(project.base, json={"sharing": "private"}).status_code == 200
    assert project["mia"].put(f"{project.base}/roles/oscar", json={"role": "viewer"}).json()["granted_by"] == "mia"
    assert lab.other.get(project.base).status_code == 200
    assert project["mia"].delete(f"{project.base}/roles/oscar").status_code == 204
    refused(lab.other.get(project.base), 404)


def test_a_manager_neither_deletes_nor_touches_owners(project, lab):
    refused(project["mia"].delete(project.base), 403, "owner")
    refused(project["mia"].put(f"{project.base}/roles/oscar", json={"role": "owner"}), 403, "owner")
    refused(project["mia"].put(f"{project.base}/roles/mia", json={"role": "owner"}), 403, "owner")
    refused(project["mia"].put(f"{project.base}/roles/tester", json={"role": "viewer"}), 409, "owner")
    assert lab.owner.put(f"{project.base}/roles/abe", json={"role": "owner"}).status_code == 200
    refused(project["mia"].delete(f"{project.base}/roles/abe"), 403, "owner")
    refused(project["mia"].put(f"{project.base}/roles/abe", json={"role": "viewer"}), 403, "owner")
    assert project["abe"].delete(project.base).status_code == 204  # a granted owner may
    assert lab.owner.get(project.base).status_code == 404


def test_roles_and_sharing_combine_to_the_higher_of_the_two(project, lab):
    assert lab.owner.patch(project.base, json={"sharing": "read"}).status_code == 200
    assert lab.other.get(project.base).status_code == 200 and listed(lab.other, project.id)
    refused(lab.other.post(f"{project.base}/members/m1/curves", json=ANSWER), 403, "annotator")
    assert project["ann"].post(f"{project.base}/members/m1/curves", json=ANSWER).status_code == 201
    assert lab.owner.patch(project.base, json={"sharing": "edit"}).status_code == 200
    assert lab.other.post(f"{project.base}/members/m1/curves", json=ANSWER).status_code == 201
    assert project["vic"].post(f"{project.base}/members/m1/curves", json=ANSWER).status_code == 201
    refused(project["vic"].put(f"{project.base}/roles/oscar", json={"role": "viewer"}), 403)  # roles stay the roles'


def test_bad_grants_are_refused_and_grants_are_audited(project, lab):
    refused(lab.owner.put(f"{project.base}/roles/nobody", json={"role": "viewer"}), 404, "nobody")
    assert lab.owner.put(f"{project.base}/roles/vic", json={"role": "chief"}).status_code == 422
    refused(lab.owner.delete(f"{project.base}/roles/oscar"), 404, "no role")
    assert lab.owner.put(f"{project.base}/roles/vic", json={"role": "annotator"}).json()["role"] == "annotator"
    assert lab.owner.delete(f"{project.base}/roles/vic").status_code == 204
    refused(project["vic"].get(project.base), 404)
    events = [e for e in audit_of(lab.api.data_dir).read(limit=1000) if e["target"] == project.id]
    grants = [(e["action"], e["detail"]["user"], e["detail"]["role"]) for e in events if "role" in e["detail"]]
    assert grants[-2:] == [("collection.grant", "vic", "annotator"), ("collection.revoke", "vic", "annotator")]
    assert events[-2]["detail"]["previous"] == "viewer" and events[-2]["user"] == "tester"
    assert lab.admin.put(f"{project.base}/roles/vic", json={"role": "owner"}).status_code == 200  # admins lab-wide


def with_members(project: Project, lab: Lab, more: int) -> list[str]:
    """Add ``more`` members on new shapes and wait for their bases; returns every member's id."""
    added = lab.owner.post(f"{project.base}/members", json={"shapes": [lab.new_shape() for _ in range(more)]})
    for member in added.raise_for_status().json()["members"]:
        if member["basis_job"]:
            lab.wait_job(lab.owner, member["basis_job"])
    return [member["id"] for member in lab.owner.get(project.base).json()["members"]]


def answer(client: httpx.Client, project: Project, member: str) -> httpx.Response:
    return client.post(f"{project.base}/members/{member}/curves", json=ANSWER)


def test_members_are_spread_over_annotators_who_answer_only_their_own(project, lab):
    assert with_members(project, lab, 3) == ["m1", "m2", "m3", "m4"]
    for name in ("ann", "rita", "vic"):
        refused(project[name].post(f"{project.base}/assign", json={"annotators": ["ann"]}), 403, "manager")
    refused(project["mia"].post(f"{project.base}/assign", json={"annotators": ["vic"]}), 409, "annotator role")
    spread = project["mia"].post(f"{project.base}/assign", json={"annotators": ["ann", "abe"]}).json()
    assert [(m["member"], m["assignee"]) for m in spread["members"]] == [
        ("m1", "ann"),
        ("m2", "abe"),
        ("m3", "ann"),
        ("m4", "abe"),
    ]
    assert [(a["user"], a["assigned"], a["done"], a["next"]) for a in spread["annotators"]] == [
        ("abe", 2, 0, "m2"),
        ("ann", 2, 1, "m3"),  # m1 came with the session's curves
    ]

    assert answer(project["ann"], project, "m1").status_code == 201
    body = refused(answer(project["ann"], project, "m2"), 403, "not assigned to you")
    assert "abe" not in body["detail"]
    assert answer(project["abe"], project, "m2").status_code == 201
    assert answer(project["mia"], project, "m3").status_code == 201  # managers answer every member
    m4_session = lab.owner.get(project.base).json()["members"][3]["session"]
    refused(project["ann"].post(f"/sessions/{m4_session}/curves", json=CURVE), 403)
    assert project["abe"].post(f"/sessions/{m4_session}/curves", json=CURVE).status_code == 201

    work = project["ann"].get("/me/work").raise_for_status().json()
    assert [(w["collection"], w["member"], w["done"]) for w in work] == [
        (project.id, "m1", True),
        (project.id, "m3", True),
    ]
    progress = project["rita"].get(f"{project.base}/assignments").json()
    assert [(a["user"], a["done"], a["next"]) for a in progress["annotators"]] == [("abe", 1, "m4"), ("ann", 2, None)]
    refused(lab.other.get(f"{project.base}/assignments"), 404)
    assert lab.other.get("/me/work").json() == []


def test_a_member_is_assigned_by_hand_and_taken_back(project, lab):
    with_members(project, lab, 1)
    assignee = f"{project.base}/members/m2/assignee"
    refused(project["ann"].put(assignee, json={"user": "ann"}), 403, "manager")
    refused(project["mia"].put(assignee, json={"user": "nobody"}), 404, "nobody")
    assert project["mia"].put(assignee, json={"user": "abe"}).json()["assignee"] == "abe"
    assert answer(project["ann"], project, "m1").status_code == 403  # assignment exists: m1 is no one's
    assert [w["member"] for w in project["abe"].get("/me/work").json() if w["collection"] == project.id] == ["m2"]
    refused(project["mia"].put(f"{project.base}/members/m9/assignee", json={"user": "abe"}), 404, "m9")
    assert project["mia"].put(assignee, json={"user": None}).json()["assignee"] is None
    assert answer(project["ann"], project, "m1").status_code == 201  # no member assigned: every annotator answers
    events = [e for e in audit_of(lab.api.data_dir).read(limit=1000) if e["target"] == project.id]
    assert [e["detail"]["user"] for e in events if e["action"] == "collection.assign"] == ["abe", None]
