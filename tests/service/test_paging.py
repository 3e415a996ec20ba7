"""Paged lists over HTTP against a real server process: ``GET /sessions``, ``/collections``, ``/shapes`` and a
session's ``/refinements`` take
``limit`` and ``offset``, answer the total in ``X-Total-Count`` (counting only what the caller may see), refuse
out-of-bounds pages with the published 422, and answer everything without ``limit``."""

from __future__ import annotations

import httpx
import pytest
from support.errors import expect
from support.lab import Lab

LISTS = ("/sessions", "/collections", "/shapes")
REFINEMENTS = "/sessions/{session_id}/refinements"


@pytest.fixture(scope="module")
def lab(module_processes, tmp_path_factory) -> Lab:
    return Lab(module_processes.api(tmp_path_factory.mktemp("paging") / "data"))


def ids(response: httpx.Response) -> list[str]:
    assert response.status_code == 200, response.text
    return [record["id"] for record in response.json()]


def pages(client: httpx.Client, path: str, limit: int) -> tuple[list[str], set[str]]:
    """Every id of the list read ``limit`` at a time, and the totals the pages said."""
    seen: list[str] = []
    totals = set()
    while True:
        response = client.get(path, params={"limit": limit, "offset": len(seen)})
        page = ids(response)
        assert len(page) <= limit
        totals.add(response.headers["X-Total-Count"])
        seen += page
        if not page:
            return seen, totals


def new_collection(lab: Lab, client: httpx.Client, **fields) -> str:
    body = {"template": lab.shapes[0], "members": [lab.shapes[1]], "k": 10, "curves": [{"waypoints": [0, 60]}]}
    made = client.post("/collections", json={**body, **fields})
    assert made.status_code == 201, made.text
    return made.json()["collection"]["id"]


def test_sessions_and_collections_page_and_count_only_what_the_caller_may_see(lab):
    pam = lab.api.client_for("pam")
    quinn = lab.api.client_for("quinn")
    pams = [lab.new_session(pam, name=f"pam {i}") for i in range(3)]
    shared = lab.new_session(quinn, name="quinn's shared", sharing="read")
    lab.new_session(quinn, name="quinn's own")

    sessions, totals = pages(pam, "/sessions", 2)
    assert sessions == [shared, *pams[::-1]]  # the most recently changed first; quinn's private one not counted
    assert totals == {"4"}
    assert ids(pam.get("/sessions")) == sessions
    assert ids(pam.get("/sessions", params={"offset": 1})) == sessions[1:]
    assert int(lab.admin.get("/sessions", params={"limit": 1}).headers["X-Total-Count"]) >= 5

    pam_collections = [new_collection(lab, pam, name=f"pam {i}") for i in range(2)]
    new_collection(lab, quinn, name="quinn's own")

    collections, totals = pages(pam, "/collections", 1)
    assert collections == pam_collections[::-1] and totals == {"2"}
    first = pam.get("/collections", params={"limit": 1, "offset": 1})
    assert ids(first) == [pam_collections[0]] and first.headers["X-Total-Count"] == "2"
    everything = pam.get("/collections")
    assert ids(everything) == collections and everything.headers["X-Total-Count"] == "2"
    assert everything.json()[0]["n_members"] == 1 and everything.json()[0]["n_curves"] == 1

    admin_total = int(lab.admin.get("/collections", params={"limit": 1}).headers["X-Total-Count"])
    assert admin_total >= 3  # the admin sees quinn's private one too
    past_the_end = pam.get("/collections", params={"limit": 5, "offset": 10})
    assert ids(past_the_end) == [] and past_the_end.headers["X-Total-Count"] == "2"


def test_shapes_page_by_name_and_upload_time_with_the_total(lab):
    newest = lab.new_shape()
    everything = lab.other.get("/shapes")  # every user sees every shape
    all_ids = ids(everything)
    order = [(s["name"], -s["uploaded_at"]) for s in everything.json()]
    assert order == sorted(order) and everything.headers["X-Total-Count"] == str(len(all_ids))
    assert all_ids[0] == newest  # the lab's shapes all have one name: the newest upload first
    paged, totals = pages(lab.other, "/shapes", 2)
    assert paged == all_ids and totals == {str(len(all_ids))}
    one = lab.owner.get("/shapes", params={"limit": 1, "offset": 1})
    assert ids(one) == all_ids[1:2] and one.json()[0]["n_vertices"] > 0


@pytest.mark.parametrize("path", LISTS)
@pytest.mark.parametrize("params", [{"limit": 0}, {"limit": 501}, {"offset": -1}, {"offset": 2**63}, {"limit": "ten"}])
def test_pages_out_of_bounds_are_refused_with_the_published_error(lab, path, params):
    expect(lab.owner.get(path, params=params), 422, "invalid")


def test_the_paged_lists_declare_their_parameters_and_header(lab):
    schema = lab.owner.get("/openapi.json").raise_for_status().json()
    for path in (*LISTS, REFINEMENTS):
        operation = schema["paths"][path]["get"]
        parameters = {p["name"]: p["schema"] for p in operation["parameters"]}
        limit = parameters["limit"].get("anyOf", [parameters["limit"]])[0]
        assert limit["minimum"] == 1 and limit["maximum"] == 500, (path, parameters)
        assert parameters["offset"]["minimum"] == 0
        assert "X-Total-Count" in operation["responses"]["200"]["headers"]
        assert "422" in operation["responses"]


def test_a_sessions_refinements_page_oldest_first_counting_what_the_caller_may_see(lab):
    pam, quinn, rita = (lab.api.client_for(name) for name in ("pam", "quinn", "rita"))
    shared = lab.new_session(pam, sharing="read")
    lab.add_curve(pam, shared)
    made = [lab.refined(pam, shared)["id"] for _ in range(2)] + [lab.refined(quinn, shared)["id"]]
    path = REFINEMENTS.format(session_id=shared)

    for client in (pam, quinn):  # each sees their own and the other's finished ones
        assert pages(client, path, 2) == (made, {"3"})
    everything = pam.get(path)
    assert ids(everything) == made and everything.headers["X-Total-Count"] == "3"
    second = quinn.get(path, params={"limit": 1, "offset": 1})
    assert ids(second) == made[1:2] and second.json()[0]["state"] == "finished"
    assert second.json()[0]["result"]["revision"] >= 1
    expect(pam.get(path, params={"limit": 501}), 422, "invalid")
    expect(pam.get(path, params={"offset": -1}), 422, "invalid")

    private = lab.new_session(pam)
    expect(rita.get(REFINEMENTS.format(session_id=private), params={"limit": 1}), 404, "not_found")
    empty = pam.get(REFINEMENTS.format(session_id=private), params={"limit": 5})
    assert ids(empty) == [] and empty.headers["X-Total-Count"] == "0"


def test_lists_need_credentials(lab):
    for path in LISTS:
        assert lab.anonymous.get(path, params={"limit": 1}).status_code == 401
