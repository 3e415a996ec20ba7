"""Keeping sessions, shapes and collections tidy, over HTTP against a real server process: sessions are named at
creation (by their shapes by default), renamed, found by a text in their name or shape names, listed newest change
first with or without the collections' member sessions; shapes are listed by name; a collection refuses a shape
that is a member already, removes a member with its session, and runs only its members that are ready."""

from __future__ import annotations

import httpx
import pytest
from support.errors import expect
from support.lab import CURVE, K, Lab
from support.shapes import ellipsoid, off_bytes


@pytest.fixture(scope="module")
def lab(module_processes, tmp_path_factory) -> Lab:
    return Lab(module_processes.api(tmp_path_factory.mktemp("manage") / "data"))


@pytest.fixture(scope="module")
def pair(lab) -> tuple[str, str]:
    """Two shapes with bases, uploaded as cat.off and lion.off."""
    cat, lion = (named_shape(lab, name, scale) for name, scale in (("cat", 1.3), ("lion", 1.4)))
    for shape in (cat, lion):
        lab.basis(lab.owner, shape)
    return cat, lion


def named_shape(lab: Lab, name: str, scale: float) -> str:
    response = lab.owner.post("/shapes", files={"file": (f"{name}.off", off_bytes(ellipsoid(8, 16, scale=scale)))})
    assert response.status_code == 201, response.text
    return response.json()["id"]


def listed(client: httpx.Client, **params) -> list[dict]:
    response = client.get("/sessions", params=params)
    assert response.status_code == 200, response.text
    assert int(response.headers["X-Total-Count"]) >= len(response.json())
    return response.json()


def test_a_session_is_named_by_its_shapes_renamed_and_found(lab, pair):
    cat, lion = pair
    owner = lab.api.client_for("nina")
    plain = owner.post("/sessions", json={"source": cat, "target": lion, "k": K}).raise_for_status().json()
    assert plain["name"] == "cat -> lion"
    named = owner.post("/sessions", json={"source": lion, "target": cat, "k": K, "name": "  Paws 100%  "})
    assert named.json()["name"] == "Paws 100%"  # trimmed

    entries = listed(owner)
    assert [e["id"] for e in entries] == [named.json()["id"], plain["id"]]  # the most recently changed first
    assert entries[1] | {"source_name": "cat", "target_name": "lion", "owner": "nina", "n_curves": 0} == entries[1]
    assert entries[1]["collection"] is None and entries[1]["created_at"] <= entries[1]["updated_at"]

    renamed = owner.patch(f"/sessions/{plain['id']}", json={"name": " cat, front legs "})
    assert renamed.status_code == 200 and renamed.json()["name"] == "cat, front legs"
    assert renamed.json()["revision"] == plain["revision"] + 1
    assert [e["id"] for e in listed(owner)] == [plain["id"], named.json()["id"]]  # the rename is a change

    assert {e["id"] for e in listed(owner, q="LION")} == {plain["id"], named.json()["id"]}  # a shape's name
    assert [e["id"] for e in listed(owner, q="front")] == [plain["id"]]  # the session's name
    assert [e["id"] for e in listed(owner, q="100%")] == [named.json()["id"]]  # % is itself, not a wildcard
    assert listed(owner, q="0%") and listed(owner, q="x%") == []
    page = owner.get("/sessions", params={"q": "lion", "limit": 1})
    assert len(page.json()) == 1 and page.headers["X-Total-Count"] == "2"

    expect(owner.patch(f"/sessions/{plain['id']}", json={"name": "   "}), 422, "invalid", "name")
    unchanged = owner.patch(f"/sessions/{plain['id']}", json={})  # nothing to change
    assert unchanged.status_code == 200 and unchanged.json()["revision"] == renamed.json()["revision"]
    expect(owner.patch(f"/sessions/{plain['id']}", json={"name": "x" * 201}), 422, "invalid", "name")
    both = owner.patch(f"/sessions/{plain['id']}", json={"name": "shared", "sharing": "read"}).json()
    assert (both["name"], both["sharing"]) == ("shared", "read")


@pytest.mark.parametrize(
    ("sharing", "rename", "share", "delete"),
    [("private", 404, 404, 404), ("read", 403, 403, 403), ("edit", 200, 403, 403)],
)
def test_who_may_rename_share_and_delete_a_session(lab, pair, sharing, rename, share, delete):
    session = lab.new_session(lab.owner, source=pair[0], target=pair[1], sharing=sharing)
    path = f"/sessions/{session}"
    assert lab.other.patch(path, json={"name": "mine now"}).status_code == rename
    assert lab.other.patch(path, json={"name": "mine now", "sharing": "edit"}).status_code == share
    assert lab.other.delete(path).status_code == delete
    expected_name = "mine now" if rename == 200 else "cat -> lion"
    assert lab.owner.get(path).json()["name"] == expected_name
    assert lab.admin.patch(path, json={"name": "tidied"}).json()["name"] == "tidied"
    assert lab.owner.delete(path).status_code == 204
    assert lab.owner.get(path).status_code == 404


def test_shapes_are_listed_by_name_then_upload_time(lab):
    later = [named_shape(lab, name, scale) for name, scale in (("zebra", 1.51), ("aardvark", 1.52))]
    shapes = lab.owner.get("/shapes").raise_for_status().json()
    names = [s["name"] for s in shapes]
    assert names == sorted(names)
    assert names[0] == "aardvark" and shapes[0]["id"] == later[1]
    assert all(s["uploaded_at"] > 0 for s in shapes)
    first = lab.owner.get("/shapes", params={"limit": 1}).json()
    assert [s["id"] for s in first] == [later[1]]


def new_collection(lab: Lab, template: str, members: list[str]) -> dict:
    body = {"name": "cats", "template": template, "members": members, "k": K, "curves": [{"waypoints": [0, 60]}]}
    made = lab.owner.post("/collections", json=body)
    assert made.status_code == 201, made.text
    return made.json()


def test_a_collection_is_kept_tidy(lab, pair):
    cat, lion = pair
    tiger = named_shape(lab, "tiger", 1.6)
    lab.basis(lab.owner, tiger)
    view = new_collection(lab, cat, [lion, tiger])
    collection = view["collection"]["id"]
    assert [(m["id"], m["shape_name"]) for m in view["members"]] == [("m1", "lion"), ("m2", "tiger")]
    members = f"/collections/{collection}/members"

    again = lab.owner.post(members, json={"shapes": [tiger]})
    expect(again, 409, "conflict", "'tiger'", "m2")
    twice = named_shape(lab, "puma", 1.61)
    expect(lab.owner.post(members, json={"shapes": [twice, twice]}), 409, "conflict", "'puma'", "twice")
    assert len(lab.owner.get(f"/collections/{collection}").json()["members"]) == 2  # nothing was added

    member_sessions = {m["session"] for m in view["members"]}
    own = {e["id"] for e in listed(lab.owner, in_collection=False)}
    assert own and not own & member_sessions
    of_members = {e["id"]: e for e in listed(lab.owner, in_collection=True)}
    assert member_sessions <= set(of_members)
    assert {(of_members[s]["collection"], of_members[s]["name"]) for s in member_sessions} == {
        (collection, "cats: lion"),
        (collection, "cats: tiger"),
    }

    runs = f"/collections/{collection}/runs"
    refine = {"converter": "nearest-neighbor"}
    refused = lab.owner.post(runs, json=refine)
    expect(refused, 409, "conflict", "m1 (lion)", "m2 (tiger)", "only_ready")
    expect(lab.owner.post(runs, json={**refine, "only_ready": True}), 409, "conflict", "no member")
    answer = {"template_curve": "t1", "target": CURVE["target"]}
    lab.owner.post(f"{members}/m1/curves", json=answer).raise_for_status()
    run = lab.owner.post(runs, json={**refine, "only_ready": True})
    assert run.status_code == 202, run.text
    assert [m["member"] for m in run.json()["members"]] == ["m1"]
    job = lab.wait_job(lab.owner, run.json()["members"][0]["job"])
    assert job["state"] == "finished", job
    result_file = next(iter(job["links"].values()))
    assert lab.owner.get(result_file).status_code == 200

    expect(lab.other.delete(f"{members}/m1"), 404, "not_found")  # a private collection of another user
    removed = lab.owner.delete(f"{members}/m1")
    assert removed.status_code == 204, removed.text
    after = lab.owner.get(f"/collections/{collection}").json()
    assert [m["id"] for m in after["members"]] == ["m2"]
    assert r_members(lab, collection, run.json()["id"]) == []  # it left the run
    expect(lab.owner.get(result_file), 404, "not_found")  # its results went with it
    gone = next(m["session"] for m in view["members"] if m["id"] == "m1")
    expect(lab.owner.get(f"/sessions/{gone}"), 404, "not_found")
    expect(lab.owner.delete(f"{members}/m1"), 404, "not_found", "m1")
    assert lab.owner.post(members, json={"shapes": [lion]}).status_code == 201  # a removed shape may come back


def r_members(lab: Lab, collection: str, run: str) -> list[dict]:
    return lab.owner.get(f"/collections/{collection}/runs/{run}").raise_for_status().json()["members"]


def test_the_session_list_declares_its_filters(lab):
    schema = lab.owner.get("/openapi.json").raise_for_status().json()
    parameters = {p["name"] for p in schema["paths"]["/sessions"]["get"]["parameters"]}
    assert {"q", "in_collection", "limit", "offset"} <= parameters
    assert "/collections/{collection_id}/members/{member_id}" in schema["paths"]
    entry = schema["components"]["schemas"]["SessionSummary"]["properties"]
    assert {"source_name", "target_name", "owner", "created_at", "updated_at", "n_curves", "collection"} <= set(entry)
