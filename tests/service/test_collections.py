"""Collections over HTTP against real processes: a small collection end to end on Redis with two workers
(template curves from a session, member curves given as a script would, a batch run, the archive checked against
each member session's maps), access and bad input; and the maps composed through the template against FAUST's
ground truth (embedded jobs)."""

from __future__ import annotations

import io
import json
import subprocess
import sys
import time
import zipfile

import numpy as np
from support.shapes import ellipsoid, off_bytes

from curvefm.evaluation import evaluate_map, identity_truth
from curvefm.geometry import farthest_point_sampling, load_mesh

K = 10
CURVES = ([0, 60], [20, 100], [5, 120])


def upload(client, mesh) -> str:
    return client.post("/shapes", files={"file": ("shape.off", off_bytes(mesh))}).raise_for_status().json()["id"]


def wait_for(client, path: str, done, timeout: float = 120) -> dict:
    deadline = time.monotonic() + timeout
    while not done(body := client.get(path).raise_for_status().json()):
        assert time.monotonic() < deadline, body
        time.sleep(0.1)
    return body


def bases_ready(view: dict) -> bool:
    return all(m["basis"] == "ready" for m in view["members"])


def run_ended(run: dict) -> bool:
    return run["state"] in ("finished", "failed")


def test_collection_end_to_end_on_two_workers(processes, tmp_path, redis_url, redis_prefix):
    for name in ("w1", "w2"):
        processes.worker(redis_url, redis_prefix, name, tmp_path / "data")
    api = processes.api(tmp_path / "data", redis_url, env={"CURVEFM_QUEUE_PREFIX": redis_prefix})
    client = api.client
    template, first, second = (
        upload(client, ellipsoid(8, 16, radii)) for radii in ((1, 0.7, 0.5), (1, 1, 1), (1.1, 0.6, 0.55))
    )
    for shape in (template, first):
        job = client.post(f"/shapes/{shape}/bases", json={"k": K}).raise_for_status().json()
        assert api.wait_job(job["id"])["state"] == "finished"
    session = client.post("/sessions", json={"source": template, "target": first, "k": K}).raise_for_status().json()
    for ends in CURVES[:2]:
        client.post(f"/sessions/{session['id']}/curves", json={"source": ends, "target": ends}).raise_for_status()

    body = {"name": "ellipsoids", "template": template, "from_session": session["id"], "members": [second]}
    view = client.post("/collections", json=body).raise_for_status().json()
    collection = view["collection"]
    cid = collection["id"]
    assert [c["id"] for c in collection["curves"]] == ["t1", "t2"]
    assert [(m["shape"], m["curves_done"], m["curves_total"]) for m in view["members"]] == [
        (first, 2, 2),
        (second, 0, 2),
    ]
    view = wait_for(client, f"/collections/{cid}", bases_ready)

    for curve, ends in zip(("t1", "t2"), CURVES, strict=False):  # the second member's curves, as a script gives them
        edit = client.post(f"/collections/{cid}/members/m2/curves", json={"template_curve": curve, "target": ends})
        assert edit.raise_for_status().json()["curve"]["spec"]["template_curve"] == curve
    again = client.post(f"/collections/{cid}/members/m2/curves", json={"template_curve": "t2", "target": CURVES[2]})
    assert again.raise_for_status().json()["map"]["n_curves"] == 2  # answering t2 again replaced its answer
    view = client.get(f"/collections/{cid}").json()
    assert [m["curves_done"] for m in view["members"]] == [2, 2]

    run = client.post(f"/collections/{cid}/runs", json={"converter": "nearest-neighbor"}).raise_for_status().json()
    assert sorted(m["member"] for m in run["members"]) == ["m1", "m2"]
    run = wait_for(client, f"/collections/{cid}/runs/{run['id']}", run_ended)
    assert run["state"] == "finished" and run["counts"] == {"finished": 2}, run
    workers = {client.get(f"/jobs/{m['job']}").json()["worker"] for m in run["members"]}
    assert all(worker.startswith(redis_prefix) for worker in workers)

    archive = np.load(io.BytesIO(client.get(f"/collections/{cid}/runs/{run['id']}/archive.npz").content))
    summary = json.loads(str(archive["summary.json"]))
    assert [m["member"] for m in summary["members"]] == ["m1", "m2"]
    assert "agreement" not in summary  # no member is annotated twice
    for member in view["members"]:
        session_map = client.get(f"/sessions/{member['session']}/map").json()
        C = archive[f"{member['id']}/C_template_to_member"]
        np.testing.assert_allclose(C, session_map["C_source_to_target"], atol=1e-12)
        np.testing.assert_allclose(
            archive[f"{member['id']}/C_member_to_template"], session_map["C_target_to_source"], atol=1e-12
        )
        to_template = archive[f"{member['id']}/map_member_to_template"]
        assert len(to_template) == 130 and to_template.min() >= 0 and to_template.max() < 130
        one = client.get(f"/collections/{cid}/runs/{run['id']}/members/{member['id']}").raise_for_status().json()
        assert one["map_member_to_template"] == to_template.tolist()
        assert one["report"]["quality"]["converted"]["coverage"] > 0
    with zipfile.ZipFile(io.BytesIO(client.get(f"/collections/{cid}/runs/{run['id']}/archive.zip").content)) as z:
        text = np.loadtxt(io.BytesIO(z.read("m2/C_template_to_member.txt")))
        assert np.array_equal(text, archive["m2/C_template_to_member"])
        assert json.loads(z.read("summary.json"))["run"] == run["id"]
    composed = client.get(f"/collections/{cid}/runs/{run['id']}/members/m1/to/m2").raise_for_status().json()
    expected = archive["m2/map_template_to_member"][archive["m1/map_member_to_template"]]
    assert composed["map_a_to_b"] == expected.tolist()
    np.testing.assert_allclose(
        composed["C_a_to_b"], archive["m2/C_template_to_member"] @ archive["m1/C_member_to_template"], atol=1e-12
    )

    rerun = client.post(f"/collections/{cid}/runs", json={"converter": "nearest-neighbor", "members": ["m2"]})
    rerun = rerun.raise_for_status().json()
    pending = client.get(f"/collections/{cid}/runs/{rerun['id']}/archive.npz")
    assert pending.status_code == 409 and "m2" in pending.json()["detail"], pending.text
    assert {m["member"]: m["carried"] for m in rerun["members"]} == {"m1": True, "m2": False}
    assert wait_for(client, f"/collections/{cid}/runs/{rerun['id']}", run_ended)["state"] == "finished"

    other = api.client_for("oscar")
    assert other.get(f"/collections/{cid}").status_code == 404
    assert other.get(f"/collections/{cid}/runs/{run['id']}/archive.npz").status_code == 404
    assert other.post(f"/collections/{cid}/members", json={"shapes": [first]}).status_code == 404
    assert cid not in [c["id"] for c in other.get("/collections").json()]
    client.patch(f"/collections/{cid}", json={"sharing": "read"}).raise_for_status()
    assert other.get(f"/collections/{cid}").status_code == 200
    assert other.get(f"/sessions/{view['members'][0]['session']}").status_code == 200  # members shared alike
    assert other.post(f"/collections/{cid}/members", json={"shapes": [first]}).status_code == 403
    runs_before = client.get(f"/collections/{cid}").json()
    assert other.post(f"/collections/{cid}/runs", json={"only_ready": True}).status_code == 403  # recorded there
    assert client.get(f"/collections/{cid}").json() == runs_before

    for path in (
        "/collections/nope",
        f"/collections/{cid}/runs/r99",
        f"/collections/{cid}/runs/r1/members/m9",
        f"/collections/{cid}/runs/r1/members/m1/to/m9",
    ):
        assert client.get(path).status_code == 404, path
    assert (
        client.post(
            f"/collections/{cid}/members/m2/curves", json={"template_curve": "t9", "target": [0, 5]}
        ).status_code
        == 404
    )
    assert client.post(f"/collections/{cid}/runs", json={"members": ["m9"]}).status_code == 404
    assert client.post(f"/collections/{cid}/members", json={"shapes": ["no-such-shape"]}).status_code == 404
    assert client.post("/collections", json={"template": first, "from_session": session["id"]}).status_code == 409
    duplicate = client.post(f"/collections/{cid}/members", json={"shapes": [first]})  # m1 already
    assert duplicate.status_code == 409 and "m1" in duplicate.json()["detail"]
    third = upload(client, ellipsoid(8, 16, (1.2, 0.5, 0.5)))
    client.post(f"/collections/{cid}/members", json={"shapes": [third]}).raise_for_status()
    no_curves = client.post(f"/collections/{cid}/runs", json={"members": ["m3"]})
    assert no_curves.status_code == 409 and "m3" in no_curves.json()["detail"]
    assert client.get(f"/collections/{cid}/runs/r1/archive.tar").status_code == 422


def test_composition_through_the_template_against_faust_ground_truth(processes, tmp_path, shared_data):
    """FAUST registrations share vertex ids, so curves from the ground truth use the same ids on every shape and
    the true map is the identity: a member-to-member map composed through the template must be about as good as
    the direct template-member maps it is made of."""
    api = processes.api(tmp_path / "data")
    client = api.client
    paths = [shared_data / "faust" / f"tr_reg_{n}.off" for n in ("000", "001", "010")]
    template, *members = (api.upload(path) for path in paths)
    meshes = [load_mesh(path) for path in paths]
    ends = farthest_point_sampling(meshes[0], 12).tolist()
    curves = [{"waypoints": pair} for pair in zip(ends[0::2], ends[1::2], strict=True)]
    body = {"template": template, "curves": curves, "members": members, "k": 40}
    cid = client.post("/collections", json=body).raise_for_status().json()["collection"]["id"]
    wait_for(client, f"/collections/{cid}", bases_ready)
    for member in ("m1", "m2"):
        for number, curve in enumerate(curves, 1):
            answer = {"template_curve": f"t{number}", "target": curve["waypoints"]}
            client.post(f"/collections/{cid}/members/{member}/curves", json=answer).raise_for_status()
    run = client.post(f"/collections/{cid}/runs", json={"converter": "nearest-neighbor"}).raise_for_status().json()
    assert wait_for(client, f"/collections/{cid}/runs/{run['id']}", run_ended)["state"] == "finished"

    archive = np.load(io.BytesIO(client.get(f"/collections/{cid}/runs/{run['id']}/archive.npz").content))
    direct = [
        evaluate_map(archive[f"{m}/map_member_to_template"], identity_truth(mesh, meshes[0]), meshes[0]).mean
        for m, mesh in (("m1", meshes[1]), ("m2", meshes[2]))
    ]
    composed = client.get(f"/collections/{cid}/runs/{run['id']}/members/m1/to/m2", params={"format": "npz"})
    p2p = np.load(io.BytesIO(composed.raise_for_status().content))["map_a_to_b"]
    error = evaluate_map(p2p, identity_truth(meshes[1], meshes[2]), meshes[2]).mean
    assert max(direct) < 0.1, direct
    assert error < 0.1 and error < 2.5 * max(direct), (error, direct)


def test_members_on_both_sides_of_the_size_switch_compose(processes, tmp_path, shared_data):
    """FAUST at k = 60: m1 answers 20 template curves (its map handed out whole, 60 x 60), m2 only 3 (the prior's
    50 x 50). Composing them either way answers the product over the template frequencies both hold, k_b x k_a
    (docs/decisions.md#composing-maps-of-different-sizes), instead of a 500."""
    api = processes.api(tmp_path / "data")
    client = api.client
    paths = [shared_data / "faust" / f"tr_reg_{n}.off" for n in ("000", "001", "010")]
    template, *members = (api.upload(path) for path in paths)
    ends = farthest_point_sampling(load_mesh(paths[0]), 40).tolist()
    curves = [{"waypoints": pair} for pair in zip(ends[0::2], ends[1::2], strict=True)]
    body = {"template": template, "curves": curves, "members": members, "k": 60}
    cid = client.post("/collections", json=body).raise_for_status().json()["collection"]["id"]
    wait_for(client, f"/collections/{cid}", bases_ready)
    for member, answered in (("m1", curves), ("m2", curves[:3])):
        for number, curve in enumerate(answered, 1):
            answer = {"template_curve": f"t{number}", "target": curve["waypoints"]}
            client.post(f"/collections/{cid}/members/{member}/curves", json=answer).raise_for_status()
    run = client.post(f"/collections/{cid}/runs", json={"converter": "nearest-neighbor"}).raise_for_status().json()
    assert wait_for(client, f"/collections/{cid}/runs/{run['id']}", run_ended, 300)["state"] == "finished"

    archive = np.load(io.BytesIO(client.get(f"/collections/{cid}/runs/{run['id']}/archive.npz").content))
    assert archive["m1/C_template_to_member"].shape == (60, 60)
    assert archive["m2/C_template_to_member"].shape == (50, 50)
    for a, b in (("m1", "m2"), ("m2", "m1")):
        response = client.get(f"/collections/{cid}/runs/{run['id']}/members/{a}/to/{b}")
        assert response.status_code == 200, response.text
        C_aT, C_Tb = archive[f"{a}/C_member_to_template"], archive[f"{b}/C_template_to_member"]
        C = np.array(response.json()["C_a_to_b"])
        assert C.shape == (len(C_Tb), C_aT.shape[1])
        np.testing.assert_allclose(C, C_Tb[:, :50] @ C_aT[:50, :], atol=1e-12)
        expected = archive[f"{b}/map_template_to_member"][archive[f"{a}/map_member_to_template"]]
        assert response.json()["map_a_to_b"] == expected.tolist()


def test_the_client_and_the_cli_make_the_same_collection(processes, tmp_path):
    """The Python client over HTTP (members uploaded together as files) and ``curvefm collection`` on a data
    directory, given the same shapes and curves, write archives with the same maps."""
    from curvefm.client import Client

    files = []
    for number, radii in enumerate(((1, 0.7, 0.5), (1, 1, 1), (1.1, 0.6, 0.55))):
        files.append(tmp_path / f"shape{number}.off")
        files[-1].write_bytes(off_bytes(ellipsoid(8, 16, radii)))
    curves = [{"waypoints": ends} for ends in CURVES]
    answers = [{"template_curve": f"t{n}", "target": ends} for n, ends in enumerate(CURVES, 1)]

    api = processes.api(tmp_path / "data")
    with Client(api.url, api.token) as client:
        collection = client.collection(client.upload(files[0]), curves=curves, k=K)
        assert [m["id"] for m in collection.upload(files[1:])] == ["m1", "m2"]
        collection.wait_bases(timeout=60)
        for member in ("m1", "m2"):
            for answer in answers:
                collection.answer(member, answer["template_curve"], answer["target"])
        run = collection.wait_run(collection.run()["id"], timeout=120)
        served = np.load(collection.archive(run["id"], tmp_path / "served.npz"))
        p2p, C = collection.composed(run["id"], "m1", "m2")
        assert np.array_equal(p2p, served["m2/map_template_to_member"][served["m1/map_member_to_template"]])

    (tmp_path / "answers.json").write_text(json.dumps({"curves": answers}))
    (tmp_path / "curves.json").write_text(json.dumps({"curves": curves}))
    cli = [sys.executable, "-m", "curvefm.cli", "collection"]
    data = ["--data", str(tmp_path / "cli-data")]
    made = subprocess.run(
        [*cli, "create", str(files[0]), "--curves", str(tmp_path / "curves.json"), "--k", str(K), *data],
        capture_output=True,
        text=True,
        check=True,
    )
    collection_id = made.stdout.split()[1]
    subprocess.run(
        [*cli, "add", collection_id, *map(str, files[1:]), "--curves", str(tmp_path / "answers.json"), *data],
        capture_output=True,
        check=True,
    )
    subprocess.run(
        [*cli, "export", collection_id, "--out", str(tmp_path / "cli.npz"), *data], capture_output=True, check=True
    )
    status = subprocess.run([*cli, "status", collection_id, *data], capture_output=True, text=True, check=True)
    assert status.stdout.count("3/3 template curves") == 2 and "finished in the newest run" in status.stdout
    written = np.load(tmp_path / "cli.npz")
    assert sorted(written.files) == sorted(served.files)
    for name in served.files:
        if name != "summary.json":
            np.testing.assert_allclose(written[name], served[name], atol=1e-10, err_msg=name)
