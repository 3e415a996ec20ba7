"""Ownership, sharing and deletes over HTTP against a real server process: private sessions do not exist for
others, shared ones are readable or editable as their owner chose, jobs and results follow their session, and
shapes and sessions are deleted only by those who may, with what they leave behind cleaned up and audited."""

from __future__ import annotations

import pytest
from support.lab import CURVE, Lab

from curvefm.access import audit_of
from curvefm.service.models import ErrorBody


@pytest.fixture(scope="module")
def lab(module_processes, tmp_path_factory) -> Lab:
    return Lab(module_processes.api(tmp_path_factory.mktemp("sharing") / "data"))


def expect(response, status: int, kind: str, *words: str) -> dict:
    assert response.status_code == status, response.text
    body = ErrorBody.model_validate(response.json())
    assert body.error == kind
    for word in words:
        assert word in body.detail, body
    return response.json()


def listed(client, session_id: str) -> bool:
    return session_id in {s["id"] for s in client.get("/sessions").raise_for_status().json()}


def share(client, session_id: str, sharing: str):
    return client.patch(f"/sessions/{session_id}", json={"sharing": sharing})


def audited(lab: Lab, action: str, target: str) -> list[dict]:
    return [e for e in audit_of(lab.api.data_dir).read(limit=1000) if (e["action"], e["target"]) == (action, target)]


def test_a_private_session_does_not_exist_for_other_users(lab):
    session_id = lab.new_session(name="mine")
    record = lab.owner.get(f"/sessions/{session_id}").json()
    assert (record["owner"], record["sharing"]) == ("tester", "private")

    unknown = lab.other.get("/sessions/0123456789abcdef").json()
    hidden = expect(lab.other.get(f"/sessions/{session_id}"), 404, "not_found", "private", "not shared it with you")
    assert hidden["detail"] == unknown["detail"].replace("0123456789abcdef", session_id)  # nothing tells them apart
    base = f"/sessions/{session_id}"
    expect(lab.other.get(f"{base}/map"), 404, "not_found")
    expect(lab.other.get(f"{base}/transfer"), 404, "not_found")
    expect(lab.other.post(f"{base}/curves", json=CURVE), 404, "not_found")
    expect(lab.other.post(f"{base}/refine", json={}), 404, "not_found")
    expect(share(lab.other, session_id, "edit"), 404, "not_found")
    expect(lab.other.delete(base), 404, "not_found")

    assert listed(lab.owner, session_id) and listed(lab.admin, session_id) and not listed(lab.other, session_id)
    assert lab.admin.get(f"{base}/map").status_code == 200
    assert audited(lab, "session.create", session_id)[0]["user"] == "tester"


def test_read_sharing_lets_others_read_and_refine_but_not_change(lab):
    session_id = lab.new_session()
    lab.add_curve(lab.owner, session_id)
    shared = share(lab.owner, session_id, "read").raise_for_status().json()
    assert shared["sharing"] == "read" and len(shared["curves"]) == 1

    base = f"/sessions/{session_id}"
    assert lab.other.get(base).json()["sharing"] == "read" and listed(lab.other, session_id)
    assert lab.other.get(f"{base}/map").status_code == 200
    assert lab.other.get(f"{base}/transfer", params={"function": "xyz"}).status_code == 200
    job = lab.refined(lab.other, session_id)
    assert job["owner"] == "oscar"
    body = expect(lab.other.post(f"{base}/curves", json=CURVE), 403, "forbidden", "read-only")
    assert "tester" not in body["detail"]  # a refusal names no one
    expect(lab.other.delete(f"{base}/curves/c1"), 403, "forbidden", "read-only")
    expect(share(lab.other, session_id, "edit"), 403, "forbidden", "owner")
    expect(lab.other.delete(base), 403, "forbidden", "owner")
    assert len(lab.owner.get(base).json()["curves"]) == 1
    assert audited(lab, "session.share", session_id)[-1]["detail"] == {"sharing": "read"}


def test_edit_sharing_lets_others_change_curves_until_it_is_private_again(lab):
    session_id = lab.new_session(sharing="edit")  # shared from the start
    base = f"/sessions/{session_id}"
    curve = lab.add_curve(lab.other, session_id)
    assert [c["id"] for c in lab.owner.get(base).json()["curves"]] == [curve]
    expect(share(lab.other, session_id, "private"), 403, "forbidden", "owner")
    expect(lab.other.delete(base), 403, "forbidden")

    share(lab.owner, session_id, "private").raise_for_status()
    expect(lab.other.get(base), 404, "not_found")
    assert not listed(lab.other, session_id)


def test_admins_manage_every_session(lab):
    session_id = lab.new_session(lab.other)
    assert share(lab.admin, session_id, "read").raise_for_status().json()["owner"] == "oscar"
    assert lab.admin.delete(f"/sessions/{session_id}").status_code == 204
    expect(lab.other.get(f"/sessions/{session_id}"), 404, "not_found")
    assert audited(lab, "session.delete", session_id)[0]["user"] == "ada"


def test_jobs_and_result_files_follow_their_session(lab):
    session_id = lab.new_session()
    lab.add_curve(lab.owner, session_id)
    job = lab.refined(lab.owner, session_id)
    assert job["owner"] == "tester"
    file = job["links"]["map_target_to_source.txt"]
    expect(lab.other.get(f"/jobs/{job['id']}"), 404, "not_found")
    expect(lab.other.get(file), 404, "not_found")

    share(lab.owner, session_id, "read").raise_for_status()
    assert lab.other.get(f"/jobs/{job['id']}").json()["state"] == "finished"
    assert lab.other.get(file).content == lab.owner.get(file).content
    expect(lab.other.delete(f"/jobs/{job['id']}"), 403, "forbidden", "started job")

    share(lab.owner, session_id, "private").raise_for_status()
    expect(lab.other.get(file), 404, "not_found")


def test_basis_jobs_are_seen_by_all_and_canceled_or_retried_by_their_owner(lab):
    job = lab.basis(lab.owner, lab.shapes[0])  # the basis exists: the job finishes at once
    assert job["owner"] == "tester"
    assert lab.other.get(f"/jobs/{job['id']}").json()["id"] == job["id"]
    expect(lab.other.delete(f"/jobs/{job['id']}"), 403, "forbidden", "started job")
    expect(lab.other.post(f"/jobs/{job['id']}/retry"), 403, "forbidden", "started job")
    expect(lab.owner.delete(f"/jobs/{job['id']}"), 409, "conflict", "finished")


def test_a_refinement_of_a_deleted_session_is_not_run_again(lab):
    session_id = lab.new_session()
    lab.add_curve(lab.owner, session_id)
    job = lab.refined(lab.owner, session_id)
    assert lab.owner.delete(f"/sessions/{session_id}").status_code == 204
    expect(lab.owner.post(f"/jobs/{job['id']}/retry"), 409, "conflict", session_id, "deleted")
    assert not list((lab.api.data_dir / "sessions").glob(f"{session_id}.*"))


def test_deleting_a_session_deletes_its_results(lab):
    session_id = lab.new_session()
    lab.add_curve(lab.owner, session_id)
    jobs = [lab.refined(lab.owner, session_id) for _ in range(2)]
    results = [lab.api.data_dir / "results" / job["id"] for job in jobs]
    assert all(folder.is_dir() for folder in results)

    assert lab.owner.delete(f"/sessions/{session_id}").status_code == 204
    assert not any(folder.exists() for folder in results)
    assert not list((lab.api.data_dir / "sessions").glob(f"{session_id}.*"))
    expect(lab.owner.get(f"/sessions/{session_id}"), 404, "not_found")
    expect(lab.owner.get(jobs[0]["links"]["map_target_to_source.txt"]), 404, "not_found")
    expect(lab.owner.delete(f"/sessions/{session_id}"), 404, "not_found")


def test_a_shape_in_use_is_not_deleted_and_the_answer_names_the_sessions(lab):
    shape = lab.new_shape()
    lab.basis(lab.owner, shape)
    mine = lab.new_session(source=shape, target=lab.shapes[1])
    theirs = lab.new_session(lab.other, source=lab.shapes[0], target=shape)

    body = expect(lab.owner.delete(f"/shapes/{shape}"), 409, "conflict", mine, "1 private record(s) of other users")
    assert theirs not in body["detail"]
    expect(lab.admin.delete(f"/shapes/{shape}"), 409, "conflict", mine, theirs)
    expect(lab.owner.delete(f"/shapes/{shape}/bases"), 409, "conflict", mine)
    expect(lab.other.delete(f"/shapes/{shape}"), 403, "forbidden", "uploader")

    for client, session_id in ((lab.owner, mine), (lab.other, theirs)):
        assert client.delete(f"/sessions/{session_id}").status_code == 204
    assert lab.owner.delete(f"/shapes/{shape}").status_code == 204
    expect(lab.owner.get(f"/shapes/{shape}"), 404, "not_found")
    assert shape not in {s["id"] for s in lab.owner.get("/shapes").json()}
    assert not list((lab.api.data_dir / "meshes").glob(f"{shape}.*"))
    assert not (lab.api.data_dir / "bases" / shape).exists()
    assert audited(lab, "shape.delete", shape)[0]["user"] == "tester"


def test_every_uploader_of_a_shape_may_delete_it_and_its_bases(lab):
    shape = lab.new_shape()
    expect(lab.other.delete(f"/shapes/{shape}/bases"), 403, "forbidden", "uploader")
    assert lab.upload(lab.other, lab.meshes[shape]) == shape  # the same content: the same shape
    assert lab.owner.get(f"/shapes/{shape}").json()["uploaders"] == ["tester", "oscar"]

    lab.basis(lab.other, shape)
    assert lab.other.get(f"/shapes/{shape}").json()["bases"]
    after = lab.other.delete(f"/shapes/{shape}/bases").raise_for_status().json()
    assert after["bases"] == [] and not (lab.api.data_dir / "bases" / shape).exists()
    assert lab.basis(lab.owner, shape)["state"] == "finished"  # requesting computes it again
    assert lab.other.delete(f"/shapes/{shape}").status_code == 204
    assert audited(lab, "shape.bases.delete", shape)[0]["user"] == "oscar"
