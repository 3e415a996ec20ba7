"""curvefm.client against a real API process: the README's notebook example, typed errors with the server's
messages, jobs (progress, state, cancel), and the token from CURVEFM_TOKEN."""

from __future__ import annotations

import numpy as np
import pytest
from support.processes import add_user
from support.shapes import save_demo_shapes

from curvefm.client import Client, Curve, JobFailed
from curvefm.errors import Conflict, Forbidden, InvalidInput, NotFound, Unauthenticated
from curvefm.service.demo import demo_shapes

K = 20
CURVES = [([10, 2000], [10, 2000]), ([500, 3500], [500, 3500]), ([100, 4000], [100, 4000])]
"""Waypoints on the demo shapes, which share their vertex ids."""


@pytest.fixture(scope="module")
def api(module_processes, tmp_path_factory):
    return module_processes.api(tmp_path_factory.mktemp("client") / "data")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    return save_demo_shapes(tmp_path_factory.mktemp("shapes"))


@pytest.fixture(scope="module")
def client(api):
    with Client(api.url, token=api.token) as client:
        yield client


@pytest.fixture(scope="module")
def shape_ids(client, files):
    ids = [client.upload(path) for path in files]
    for shape_id in ids:
        client.basis(shape_id, k=K).wait(progress=False)
    return ids


def test_the_notebook_example(client, api, shape_ids, files, capsys):
    src, tgt = shape_ids
    assert client.upload(files[0]) == src  # the content hash: the same mesh, the same id
    s = client.session(src, tgt, k=K)
    added = [s.add_curve(source=source, target=target) for source, target in CURVES]
    assert [c.id for c in s.curves] == [c.id for c in added] and isinstance(added[0], Curve)
    assert added[0].path_source[0] == CURVES[0][0][0] and added[0].path_source[-1] == CURVES[0][0][1]

    C = s.map()
    served = api.client.get(f"/sessions/{s.id}/map").json()
    assert C.shape == (K, K) and np.array_equal(C, np.array(served["C_source_to_target"]))
    assert np.array_equal(s.map("target_to_source"), np.array(served["C_target_to_source"]))
    stated = s.solve()
    assert stated == served["solve"] and stated["size"] == K and stated["energy"] == "combined"
    assert stated["summary"] == f"combined; {K} x {K}" and stated["weights"]["alpha"] == s.record["alpha"]

    job = s.refine("nearest-neighbor")
    r = job.wait()
    assert "refine" in capsys.readouterr().err  # the progress bar
    assert job.state == "finished" and r.revision == s.refresh()["revision"]
    for name, array in (
        ("map_target_to_source.txt", r.map_target_to_source),
        ("map_source_to_target.txt", r.map_source_to_target),
    ):
        text = api.client.get(f"/jobs/{r.job_id}/files/{name}").raise_for_status().text
        assert np.array_equal(array, np.loadtxt(text.splitlines(), dtype=int)), name
    assert len(r.map_target_to_source) == len(demo_shapes()[1].file_ids)
    assert np.array_equal(r.C_source_to_target, C) and r.result["solve"] == stated  # not refined: the session's
    assert set(r.files) >= {"map_target_to_source.txt", "target_textured.obj"}


def test_removing_a_curve_changes_the_map(client, shape_ids):
    s = client.session(*shape_ids, k=K)
    first, second = (s.add_curve(source=a, target=b) for a, b in CURVES[:2])
    with_both = s.map()
    s.remove_curve(second)
    assert [c.id for c in s.curves] == [first.id]
    assert not np.allclose(s.map(), with_both)


def test_a_suggested_curve_is_added_as_it_came(client, shape_ids):
    session = client.session(*shape_ids, k=K)
    session.add_curve(*CURVES[0])
    suggested = session.suggestion(paths=True)
    assert suggested["revision"] == session.refresh()["revision"] and len(set(suggested["source"])) == 2
    curve = session.add_curve(suggested["source"], suggested["target"])
    assert [curve.path_source[0], curve.path_source[-1]] == suggested["source"]
    assert [curve.path_target[0], curve.path_target[-1]] == suggested["target"]
    assert list(curve.path_source) == suggested["path_source"] and list(curve.path_target) == suggested["path_target"]


def test_error_answers_raise_the_projects_exceptions_with_the_servers_message(client, shape_ids):
    s = client.session(*shape_ids, k=K)
    with pytest.raises(Conflict, match="out of range") as error:
        s.add_curve(source=[0, 10**6], target=[0, 1])
    assert error.value.status == 409 and error.value.body["error"] == "conflict"
    with pytest.raises(NotFound, match="no-such-session"):
        client.open_session("no-such-session")
    with pytest.raises(InvalidInput) as error:
        client.session(*shape_ids, k=0)
    assert error.value.status == 422 and error.value.body["fields"]
    with pytest.raises(Conflict, match="no curves"):
        s.refine()


def test_the_token_comes_from_curvefm_token(api, monkeypatch):
    monkeypatch.setenv("CURVEFM_TOKEN", api.token)
    with Client(api.url) as client:
        assert isinstance(client.sessions(), list)
    monkeypatch.delenv("CURVEFM_TOKEN")
    with Client(api.url) as client, pytest.raises(Unauthenticated, match="needs credentials") as error:
        client.sessions()
    assert error.value.status == 401


def test_a_canceled_job_ends_canceled_and_waiting_on_it_raises(client, shape_ids):
    s = client.session(*shape_ids, k=K)
    s.add_curve(source=CURVES[0][0], target=CURVES[0][1])
    job = s.refine("rhm").cancel()  # a running job stops at its next progress report
    with pytest.raises(JobFailed, match="canceled") as error:
        job.wait(timeout=60, progress=False)
    assert error.value.info["id"] == job.id and job.state == "canceled"
    assert job.cancel().info["state"] == "canceled"  # canceling again changes nothing


def test_lists_page_and_iterate(client, shape_ids):
    src, tgt = shape_ids
    made = [client.session(src, tgt, k=K, name=f"paged {i}").id for i in range(3)]
    everything = [s["id"] for s in client.sessions()]
    assert everything[:3] == made[::-1]  # the most recently changed first
    page, total = client.page("/sessions", limit=2, offset=1)
    assert [s["id"] for s in page] == everything[1:3] and total == len(everything)
    assert [s["id"] for s in client.sessions(limit=1, offset=2)] == everything[2:3]
    assert [s["id"] for s in client.iterate("/sessions", page_size=2)] == everything
    by_name = [shape for _, shape in sorted(zip((mesh.name for mesh in demo_shapes()), shape_ids, strict=True))]
    assert [s["id"] for s in client.shapes(limit=1)] == by_name[:1]
    assert [s["id"] for s in client.iterate("/shapes", page_size=1)] == [s["id"] for s in client.shapes()] == by_name
    assert client.collections(limit=5) == []
    with pytest.raises(InvalidInput):
        client.sessions(limit=0)


def test_sessions_are_named_found_and_renamed_and_members_removed(client, shape_ids):
    source, target = (mesh.name for mesh in demo_shapes())
    s = client.session(*shape_ids, k=K)
    assert s.record["name"] == f"{source} -> {target}"
    assert s.rename("tidy pair").record["name"] == "tidy pair"
    assert [entry["id"] for entry in client.sessions(query="TIDY")] == [s.id]
    c = client.collection(shape_ids[0], from_session=s.id, k=K, name="set")
    (member,) = c.info["members"]
    assert member["shape_name"] == target
    assert s.id in {e["id"] for e in client.sessions(in_collection=False)}
    assert member["session"] in {e["id"] for e in client.sessions(in_collection=True)}
    with pytest.raises(Conflict, match=target):
        c.add([shape_ids[1]])
    with pytest.raises(Conflict, match="only_ready"):
        c.run()
    c.remove(member["id"])
    assert c.info["members"] == []
    with pytest.raises(NotFound):
        client.open_session(member["session"])


def test_an_edit_on_an_old_revision_is_refused_and_changes_nothing(client, shape_ids):
    s = client.session(*shape_ids, k=K)
    seen = s.refresh()["revision"]
    first = s.add_curve(*CURVES[0], if_revision=seen)  # still at the revision this client saw
    with pytest.raises(Conflict) as error:  # another page would have seen the session before that add
        s.add_curve(*CURVES[1], if_revision=seen)
    assert error.value.status == 409 and error.value.body["revision"] == s.refresh()["revision"]
    with pytest.raises(Conflict):
        s.remove_curve(first, if_revision=seen)
    assert [c.id for c in s.curves] == [first.id]
    s.remove_curve(first, if_revision=s.refresh()["revision"])
    assert s.curves == []


def test_events_tell_a_follower_of_another_clients_edits(client, api, shape_ids):
    s = client.session(*shape_ids, k=K)
    with Client(api.url, token=api.token) as follower:
        events = follower.open_session(s.id).events()
        hello = next(events)
        assert hello["kind"] == "hello" and hello["revision"] == s.refresh()["revision"]
        s.add_curve(*CURVES[0])
        added = next(e for e in events if e["kind"] != "viewers")
        assert added["kind"] == "curve-added" and added["revision"] == s.refresh()["revision"]
        s.delete()
        assert next(e for e in events if e["kind"] not in ("viewers", "prior"))["kind"] == "deleted"
        assert list(events) == []  # the stream ended with the session


def test_roles_are_granted_listed_and_taken_away(client, api, shape_ids):
    s = client.session(*shape_ids, k=K)
    s.add_curve(*CURVES[0])
    c = client.collection(shape_ids[0], from_session=s.id, k=K, name="project")
    tokens = {name: add_user(api.data_dir, name) for name in ("annie", "vince")}
    assert c.grant("annie", "annotator")["granted_by"] == "tester"
    assert c.grant("vince", "viewer")["role"] == "viewer"
    roles = [(r["user"], r["role"]) for r in c.roles()]
    assert roles == [("tester", "owner"), ("annie", "annotator"), ("vince", "viewer")]
    answer = (CURVES[0][1],)
    with Client(api.url, token=tokens["annie"]) as annie:
        assert annie.open_collection(c.id).answer("m1", "t1", *answer).path_target[-1] == CURVES[0][1][-1]
    with Client(api.url, token=tokens["vince"]) as vince:
        seen = vince.open_collection(c.id)
        with pytest.raises(Forbidden, match="annotator"):
            seen.answer("m1", "t1", *answer)
    assert [a["user"] for a in c.assign(["annie"])["annotators"]] == ["annie"]
    with Client(api.url, token=tokens["annie"]) as annie:
        assert [(w["collection"], w["member"], w["done"]) for w in annie.my_work()] == [(c.id, "m1", True)]
    assert c.assign(member="m1", user=None)["assignee"] is None
    assert c.assignments()["annotators"] == []
    c.revoke("vince")
    assert [r["user"] for r in c.roles()] == ["tester", "annie"]
    with Client(api.url, token=tokens["vince"]) as vince, pytest.raises(NotFound):
        vince.open_collection(c.id)


def test_a_member_answer_on_an_old_revision_is_refused(client, shape_ids):
    s = client.session(*shape_ids, k=K)
    s.add_curve(*CURVES[0])
    c = client.collection(shape_ids[0], from_session=s.id, k=K, name="answered")
    (member,) = c.info["members"]
    member_session = client.open_session(member["session"])
    seen = member_session.refresh()["revision"]
    first = c.answer(member["id"], "t1", CURVES[0][1], if_revision=seen)
    with pytest.raises(Conflict) as error:  # answered again from a page that had not seen the first answer
        c.answer(member["id"], "t1", CURVES[1][1], if_revision=seen)
    assert error.value.body["revision"] == member_session.refresh()["revision"] == seen + 1
    assert [curve.path_target for curve in member_session.curves] == [first.path_target]


def test_a_member_is_reviewed_run_when_accepted_and_annotated_twice(client, api, shape_ids, tmp_path):
    s = client.session(*shape_ids, k=K)
    s.add_curve(*CURVES[0])
    c = client.collection(shape_ids[0], from_session=s.id, k=K, name="reviewed")
    tokens = {name: add_user(api.data_dir, name) for name in ("rhea", "abel", "ada")}
    c.grant("rhea", "reviewer")
    c.grant("abel", "annotator")
    c.grant("ada", "annotator")
    assert c.submit("m1")["state"] == "submitted"
    with Client(api.url, token=tokens["rhea"]) as rhea:
        reviewed = rhea.open_collection(c.id)
        back = reviewed.request_changes("m1", "t1 is off")
        assert (back["state"], back["reviewed_by"], back["comment"]) == ("changes_requested", "rhea", "t1 is off")
        c.submit("m1")
        assert reviewed.accept("m1")["state"] == "accepted"
    assert [(r["member"], r["state"]) for r in c.reviews()] == [("m1", "accepted")]
    assert [m["member"] for m in c.wait_run(c.run(only_accepted=True)["id"], timeout=120)["members"]] == ["m1"]

    assert c.annotate("m1", "abel")["further"] is True
    with Client(api.url, token=tokens["abel"]) as abel:
        abel.open_collection(c.id).answer("m1", "t1", CURVES[1][1], annotator="abel")
    assert [(a["annotator"], a["further"]) for a in c.annotations()] == [(None, False), ("abel", True)]
    assert c.annotate_many("abel") == []  # abel annotates m1 already
    assert [(a["member"], a["annotator"]) for a in c.annotate_many("ada", ["m1"])] == [("m1", "ada")]
    (member,) = c.agreement()["members"]
    assert member["member"] == "m1" and member["pairs"][0]["curves"][0]["template_curve"] == "t1"
    assert member["pairs"][0]["curves"][0]["start"] > 0  # the two answers start at different vertices

    vertices = {shape["id"]: shape["n_file_vertices"] for shape in client.shapes()}
    truth = np.arange(vertices[shape_ids[0]]) % vertices[shape_ids[1]]
    np.save(tmp_path / "m1.npy", truth)
    assert c.set_truth("m1", tmp_path / "m1.npy")["known"] == truth.size
    assert c.truth("m1")["truth"] == truth.tolist()
    scored = c.agreement()["checks"]["members"][0]["annotations"]
    assert [a["annotator"] for a in scored] == [None, "abel"] and all(a["error"] >= 0 for a in scored)
    with Client(api.url, token=tokens["abel"]) as abel:
        assert abel.open_collection(c.id).agreement()["checks"] is None
    c.remove_truth("m1")
    with pytest.raises(NotFound):
        c.truth("m1")


def test_review_comments_are_listed_added_replied_resolved_and_deleted(client, api, shape_ids):
    s = client.session(*shape_ids, k=K)
    s.add_curve(*CURVES[0])
    c = client.collection(shape_ids[0], from_session=s.id, k=K, name="commented")
    tokens = {name: add_user(api.data_dir, name) for name in ("remy", "aldo")}
    c.grant("remy", "reviewer")
    c.grant("aldo", "annotator")
    c.annotate("m1", "aldo")
    (member,) = c.info["members"]
    with Client(api.url, token=tokens["remy"]) as remy, Client(api.url, token=tokens["aldo"]) as aldo:
        events = client.open_session(member["session"]).events()
        assert next(events)["kind"] == "hello"
        reviewed, further = remy.open_collection(c.id), aldo.open_collection(c.id)
        first = reviewed.comment("m1", "t1 starts too far up", "source", CURVES[0][0][0])
        assert (first["author"], first["side"], first["vertex"]) == ("remy", "source", CURVES[0][0][0])
        assert next(e for e in events if e["kind"] not in ("viewers", "prior"))["kind"] == "comments"
        with pytest.raises(Forbidden, match="reviewer"):
            further.comment("m1", "and here", "target", 5)
        reply = further.reply("m1", first["id"], "moved it")
        assert (reply["reply_to"], reply["vertex"], reply["author"]) == (first["id"], first["vertex"], "aldo")
        assert further.resolve("m1", reply["id"])["resolved_by"] == "aldo"
        assert reviewed.resolve("m1", first["id"], resolved=False)["resolved_by"] is None
        assert [(x["id"], x["text"]) for x in c.comments("m1")] == [
            (first["id"], "t1 starts too far up"),
            (reply["id"], "moved it"),
        ]
        with pytest.raises(Forbidden, match="author"):
            further.delete_comment("m1", first["id"])
        reviewed.delete_comment("m1", first["id"])
        assert c.comments("m1") == []
        with pytest.raises(NotFound, match=first["id"]):
            reviewed.reply("m1", first["id"], "gone")
