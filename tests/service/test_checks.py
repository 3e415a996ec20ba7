"""Check members on FAUST over HTTP against a real API process: a manager gives two members their ground truth
(FAUST registrations share vertex ids, the true map is the identity), one as text and one as ``.npy``; annotators
answer the template curves, one at the true endpoints and one a few vertices beside them. The accuracy the service
reports is checked against the same error computed here from the sessions' served maps and the truth, never at a
curve end; only those who manage the collection see the truth or the accuracy, and ``curvefm collection export`` (the
operator's authority on the data directory) writes the same report, checks included, into its archive."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys

import numpy as np
from support.agreement import K, beside, faust_collection, served_map
from support.errors import expect
from support.processes import TEST_USER
from support.records import database_env

from curvefm.geometry import farthest_point_sampling, pair_geodesic_distances
from curvefm.store import Store

POINTS = 300
VERTICES = 6890
BODY_BYTES = 100_000


def text_file(ids) -> bytes:
    return "".join(f"{i}\n" for i in ids).encode()


def npy_file(ids) -> bytes:
    out = io.BytesIO()
    np.save(out, np.asarray(ids))
    return out.getvalue()


def error_by_hand(client, store, session, template, member, rows, template_ends, member_ends, mesh) -> float:
    """The session's mean error against the identity at ``rows`` away from every curve end, by sqrt(area)."""
    at_ends = np.isin(rows, template_ends) | np.isin(rows, member_ends)
    kept = rows[~at_ends]
    images = served_map(client, store, session, template, member, kept)
    return float(pair_geodesic_distances(mesh, images, kept).mean() / np.sqrt(mesh.area))


def cli_summary(data_dir, collection_id: str, out) -> dict:
    """The ``summary.json`` of ``curvefm collection export`` run on the API's data directory and records."""
    env = {**os.environ, **database_env(data_dir), "CURVEFM_AGREEMENT_POINTS": str(POINTS)}
    command = [sys.executable, "-m", "curvefm.cli", "collection", "export", collection_id, "--out", str(out)]
    subprocess.run([*command, "--data", str(data_dir)], env=env, capture_output=True, check=True)
    return json.loads(str(np.load(out)["summary.json"]))


def test_check_members_score_each_annotator_against_the_truth(processes, tmp_path, shared_data):
    api = processes.api(tmp_path / "data", env={"CURVEFM_AGREEMENT_POINTS": str(POINTS)})
    owner = api.client
    faust = faust_collection(api, shared_data, ("000", "001", "011"), ("ann", "abe"))
    base, template, members, member_meshes = faust.base, faust.template, faust.members, faust.member_meshes
    ends, curves, template_mesh = faust.ends, faust.curves, faust.template_mesh
    ann, abe = faust.clients["ann"], faust.clients["abe"]
    for member in ("m1", "m2"):
        owner.put(f"{base}/members/{member}/assignee", json={"user": "ann"}).raise_for_status()
    owner.post(f"{base}/members/m1/annotations", json={"user": "abe"}).raise_for_status()

    identity = np.arange(VERTICES)
    given = owner.put(f"{base}/members/m1/truth", files={"file": ("m1.txt", text_file(identity))})
    assert given.status_code == 200, given.text
    assert (given.json()["rows"], given.json()["known"], given.json()["set_by"]) == (VERTICES, VERTICES, TEST_USER)
    given = owner.put(f"{base}/members/m2/truth", files={"file": ("m2.npy", npy_file(identity))})
    assert given.status_code == 200, given.text
    assert owner.get(f"{base}/members/m2/truth").raise_for_status().json()["truth"] == identity.tolist()

    clicked: dict[tuple[str, str], list[int]] = {("ann", "m1"): [], ("abe", "m1"): [], ("ann", "m2"): []}
    for number, curve in enumerate(curves, 1):
        start, end = curve["waypoints"]
        answer = {"template_curve": f"t{number}", "target": [start, end]}
        for member in ("m1", "m2"):
            ann.post(f"{base}/members/{member}/curves", json=answer).raise_for_status()
            clicked["ann", member] += [start, end]
        moved = [beside(member_meshes[0], start), beside(member_meshes[0], end)]
        abe.post(
            f"{base}/members/m1/curves", params={"annotator": "abe"}, json={**answer, "target": moved}
        ).raise_for_status()
        clicked["abe", "m1"] += moved

    report = owner.get(f"{base}/agreement").raise_for_status().json()
    checks = report["checks"]
    assert [m["member"] for m in checks["members"]] == ["m1", "m2"]
    store, rows = Store(api.data_dir), farthest_point_sampling(template_mesh, POINTS)
    errors = {}
    for entry, member_id, mesh in zip(checks["members"], members, member_meshes, strict=True):
        for scored in entry["annotations"]:
            key = (scored["annotator"], entry["member"])
            by_hand = error_by_hand(
                owner, store, scored["session"], template, member_id, rows, ends, clicked[key], mesh
            )
            assert np.isclose(scored["error"], by_hand, rtol=1e-6), (key, scored["error"], by_hand)
            assert 0 < by_hand < 0.1  # near the identity, not it
            assert scored["scored"] == int((~np.isin(rows, ends) & ~np.isin(rows, clicked[key])).sum())
            errors[key] = by_hand
    assert sorted(errors) == sorted(clicked)  # every annotation with curves of a check member, once
    figures = {a["annotator"]: a for a in checks["annotators"]}
    assert (figures["ann"]["members"], figures["abe"]["members"]) == (2, 1)
    assert np.isclose(figures["ann"]["error"], (errors["ann", "m1"] + errors["ann", "m2"]) / 2)
    assert np.isclose(figures["abe"]["error"], errors["abe", "m1"])
    assert np.isclose(checks["error"], np.mean(list(errors.values())))

    # blind checks: annotators see no truth and no accuracy
    for annotator in (ann, abe):
        assert annotator.get(f"{base}/agreement").raise_for_status().json()["checks"] is None
        expect(annotator.get(f"{base}/members/m1/truth"), 403, "forbidden")
        expect(annotator.put(f"{base}/members/m1/truth", files={"file": ("t.txt", b"0\n")}), 403, "forbidden")
        expect(annotator.delete(f"{base}/members/m1/truth"), 403, "forbidden")
    run = owner.post(f"{base}/runs", json={"converter": "nearest-neighbor"}).raise_for_status().json()
    assert {api.wait_job(m["job"])["state"] for m in run["members"]} == {"finished"}
    archive = f"{base}/runs/{run['id']}/archive.npz"
    summary = json.loads(str(np.load(io.BytesIO(owner.get(archive).raise_for_status().content))["summary.json"]))
    assert summary["agreement"]["checks"] == checks
    seen = json.loads(str(np.load(io.BytesIO(ann.get(archive).raise_for_status().content))["summary.json"]))
    assert seen["agreement"]["checks"] is None and seen["agreement"]["members"] == summary["agreement"]["members"]
    # the command line has the operator's authority: its archive carries the checks as a manager sees them
    assert cli_summary(api.data_dir, base.rsplit("/", 1)[1], tmp_path / "cli.npz")["agreement"] == report

    assert owner.delete(f"{base}/members/m2/truth").status_code == 204
    expect(owner.get(f"{base}/members/m2/truth"), 404, "not_found", "no ground truth")
    expect(owner.delete(f"{base}/members/m2/truth"), 404, "not_found")
    after = owner.get(f"{base}/agreement").raise_for_status().json()["checks"]
    assert [m["member"] for m in after["members"]] == ["m1"] and after["members"] == checks["members"][:1]
    audit = api.client_for("root", admin=True).get("/audit").raise_for_status().json()
    actions = [event["action"] for event in audit]
    assert actions.count("collection.truth") == 2 and actions.count("collection.truth_removed") == 1


def test_bad_truth_files_are_refused_by_name(processes, tmp_path, shared_data):
    api = processes.api(tmp_path / "data", env={"CURVEFM_MAX_BODY_BYTES": str(BODY_BYTES)})
    owner = api.client
    paths = [shared_data / "faust" / f"tr_reg_{n}.off" for n in ("000", "001")]
    template, member = (api.upload(path) for path in paths)
    body = {"template": template, "curves": [{"waypoints": [0, 100]}], "members": [member], "k": K}
    base = f"/collections/{owner.post('/collections', json=body).raise_for_status().json()['collection']['id']}"
    truth = f"{base}/members/m1/truth"
    identity = np.arange(VERTICES)

    def put(name: str, data: bytes):
        return owner.put(truth, files={"file": (name, data)})

    expect(put("short.txt", text_file(identity[:-1])), 400, "invalid", "6889 rows", "(6890)")
    expect(put("far.txt", text_file([*identity[:-1], VERTICES])), 400, "invalid", "row 6889", "out of range")
    expect(put("neg.npy", npy_file([-2, *identity[1:]])), 400, "invalid", "row 0", "out of range")
    expect(put("words.txt", b"zero\none\n"), 400, "invalid", "words.txt", "not a table of numbers")
    expect(put("half.txt", b"0.5\n" * VERTICES), 400, "invalid", "must be integers")
    expect(put("flat.npy", npy_file(np.zeros((2, VERTICES // 2), dtype=int))), 400, "invalid", "2-D")
    expect(put("floats.npy", npy_file(identity.astype(float))), 400, "invalid", "float64")
    expect(put("broken.npy", npy_file(identity)[:-5]), 400, "invalid", "broken.npy")
    expect(put("none.txt", text_file(np.full(VERTICES, -1))), 400, "invalid", "no partner")
    expect(put("one.vts", text_file(identity)), 400, "invalid", ".vts", "0")  # 1-based: id 0 is not
    expect(owner.put(f"{base}/members/m9/truth", files={"file": ("t.txt", text_file(identity))}), 404, "not_found")
    expect(owner.get(truth), 404, "not_found", "no ground truth")
    expect(put("big.txt", b"0\n" * (BODY_BYTES // 2 + 1)), 413, "too_large", "CURVEFM_MAX_BODY_BYTES")

    assert put("one.vts", text_file(identity + 1)).status_code == 200  # .vts is 1-based, as the shared data's
    assert owner.get(truth).raise_for_status().json()["truth"] == identity.tolist()
