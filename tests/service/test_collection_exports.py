"""A collection's morphometrics exports over HTTP on FAUST scans (ground truth: the same vertex id), one specimen
per member: read back by the readers of tests/support (written from the formats' specifications) and compared
with the members' curves (resampled here by arc length, independently of curvefm) and with their maps (a run's
pointwise maps exactly; the live maps against the ground truth)."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
from support.errors import expect
from support.morphometrics import read_curveslide, read_morphologika, read_tps

from curvefm.client import Client
from curvefm.geometry import load_mesh

K = 20
SCANS = ("000", "011", "021", "031")
"""The template, two members that answer every template curve, one that answers none."""
CURVES = [[412, 5891], [3057, 6617]]
SEMILANDMARKS, PSEUDO = 8, 12
MAX_PSEUDO = 40


@pytest.fixture(scope="module")
def served(module_processes, shared_data, tmp_path_factory):
    env = {"CURVEFM_MAX_PSEUDO_LANDMARKS": str(MAX_PSEUDO)}
    api = module_processes.api(tmp_path_factory.mktemp("collection-exports") / "data", env=env)
    files = [shared_data / "faust" / f"tr_reg_{n}.off" for n in SCANS]
    shapes = [api.upload(path) for path in files]
    for shape_id in shapes:
        job = api.client.post(f"/shapes/{shape_id}/bases", json={"k": K}).raise_for_status().json()
        assert api.wait_job(job["id"])["state"] == "finished"
    curves = [{"waypoints": ids} for ids in CURVES]
    body = {"template": shapes[0], "curves": curves, "members": shapes[1:3], "k": K, "name": "faust"}
    collection = api.client.post("/collections", json=body).raise_for_status().json()["collection"]
    for member in collection["members"]:
        for template_curve, ids in zip(("t1", "t2"), CURVES, strict=True):
            answer = {"template_curve": template_curve, "target": ids}
            url = f"/collections/{collection['id']}/members/{member['id']}/curves"
            api.client.post(url, json=answer).raise_for_status()
    api.client.post(f"/collections/{collection['id']}/members", json={"shapes": shapes[3:]}).raise_for_status()
    meshes = {shape_id: load_mesh(path) for shape_id, path in zip(shapes, files, strict=True)}
    return api, collection["id"], shapes, meshes


def exported(api, collection_id: str, export: str, **params) -> str:
    answer = api.client.get(f"/collections/{collection_id}/exports/{export}", params=params)
    assert answer.status_code == 200, answer.text
    name = f"collection_{collection_id}_{params.get('run', 'live')}_{export}"
    assert answer.headers["content-disposition"] == f'attachment; filename="{name}"'
    return answer.text


def arc_length_points(positions: np.ndarray, count: int) -> np.ndarray:
    """``count`` points at equal arc-length steps along a polyline, both ends included."""
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    along = np.concatenate([[0.0], np.cumsum(steps)])
    points = []
    for at in np.linspace(0.0, along[-1], count):
        i = min(int(np.searchsorted(along, at, side="right")) - 1, len(steps) - 1)
        t = 0.0 if steps[i] == 0 else (at - along[i]) / steps[i]
        points.append(positions[i] + t * (positions[i + 1] - positions[i]))
    return np.array(points)


def pseudo_rows(text: str) -> dict[str, list[dict]]:
    rows: dict[str, list[dict]] = {}
    for row in csv.DictReader(io.StringIO(text)):
        rows.setdefault(row["specimen"], []).append(row)
    return rows


def member_curves(api, collection_id: str) -> list[tuple[str, str, list[dict]]]:
    """Per member that answers every template curve: its id, shape and answers in the template's order."""
    view = api.client.get(f"/collections/{collection_id}").raise_for_status().json()
    found = []
    for member in view["members"][:2]:
        session = api.client.get(f"/sessions/{member['session']}").raise_for_status().json()
        by_template = {c["spec"]["template_curve"]: c for c in session["curves"]}
        found.append((member["id"], member["shape"], [by_template["t1"], by_template["t2"]]))
    return found


def test_live_exports_read_back_as_the_members_curves_and_maps(served, tmp_path):
    api, collection_id, shapes, meshes = served
    params = {"semilandmarks": SEMILANDMARKS, "pseudo": PSEUDO, "template": True, "complete_only": True}
    files = {name: exported(api, collection_id, name, **params) for name in ("landmarks.tps", "morphologika.txt")}
    with Client(api.url, token=api.token) as client:
        saved = client.open_collection(collection_id).landmarks("landmarks.tps", tmp_path / "l.tps", **params)
    assert saved.read_text() == files["landmarks.tps"]
    files["curveslide.csv"] = exported(
        api, collection_id, "curveslide.csv", semilandmarks=SEMILANDMARKS, complete_only=True
    )
    files["pseudo_landmarks.csv"] = exported(api, collection_id, "pseudo_landmarks.csv", **params)
    size = len(CURVES) * (SEMILANDMARKS + 2) + PSEUDO
    tps = read_tps(files["landmarks.tps"])
    names, raw = read_morphologika(files["morphologika.txt"])
    assert [name for name, _ in tps] == ["tr_reg_000", "m1 tr_reg_011", "m2 tr_reg_021"]
    assert names == [name.replace(" ", "_") for name, _ in tps] and raw.shape == (3, size, 3)
    assert all(np.allclose(points, raw[i], atol=1e-6) for i, (_, points) in enumerate(tps))
    slides = read_curveslide(files["curveslide.csv"])
    assert len(slides) == len(CURVES) * SEMILANDMARKS and slides[0] == (1, 2 * len(CURVES) + 1, 2 * len(CURVES) + 2)
    pseudo = pseudo_rows(files["pseudo_landmarks.csv"])
    chosen = [int(row["template_vertex"]) for row in pseudo["tr_reg_000"]]
    assert len(set(chosen)) == PSEUDO
    for specimen, ((member, shape, answers), (_, points)) in enumerate(
        zip(member_curves(api, collection_id), tps[1:], strict=True), 1
    ):
        mesh = meshes[shape]
        ends = np.array([mesh.vertices[c["path_target"][i]] for c in answers for i in (0, -1)])
        assert np.allclose(points[: 2 * len(CURVES)], ends, atol=1e-6)
        for i, curve in enumerate(answers):
            expected = arc_length_points(mesh.vertices[curve["path_target"]], SEMILANDMARKS + 2)[1:-1]
            first = 2 * len(CURVES) + i * SEMILANDMARKS
            assert np.allclose(points[first : first + SEMILANDMARKS], expected, atol=1e-6)
        rows = pseudo[tps[specimen][0]]
        assert [int(row["template_vertex"]) for row in rows] == chosen
        vertices = np.array([int(row["vertex"]) for row in rows])
        assert np.allclose(points[-PSEUDO:], mesh.vertices[vertices], atol=1e-6)
        assert np.allclose(points[-PSEUDO:], [[float(r[a]) for a in "xyz"] for r in rows], atol=1e-6)
        errors = np.linalg.norm(mesh.vertices[vertices] - mesh.vertices[chosen], axis=1) / np.sqrt(mesh.area)
        assert np.median(errors) < 0.1, (member, errors)  # near the ground truth: the live map carried them


def test_a_runs_pseudo_landmarks_are_its_pointwise_maps(served):
    api, collection_id, _, meshes = served
    body = {"converter": "nearest-neighbor", "only_ready": True}
    run = api.client.post(f"/collections/{collection_id}/runs", json=body).raise_for_status().json()
    for member in run["members"]:
        assert api.wait_job(member["job"])["state"] == "finished"
    params = {"run": run["id"], "pseudo": PSEUDO, "semilandmarks": 0}
    pseudo = pseudo_rows(exported(api, collection_id, "pseudo_landmarks.csv", **params))
    tps = read_tps(exported(api, collection_id, "landmarks.tps", **params))
    assert [name for name, _ in tps] == list(pseudo) == ["m1 tr_reg_011", "m2 tr_reg_021"]
    for (name, points), member in zip(tps, ("m1", "m2"), strict=True):
        maps = api.client.get(f"/collections/{collection_id}/runs/{run['id']}/members/{member}").raise_for_status()
        to_member = np.array(maps.json()["map_template_to_member"])
        rows = pseudo[name]
        chosen, vertices = (np.array([int(r[key]) for r in rows]) for key in ("template_vertex", "vertex"))
        assert np.array_equal(vertices, to_member[chosen])
        assert np.allclose(points[-PSEUDO:], meshes[maps.json()["shape"]].vertices[vertices], atol=1e-6)


def test_members_without_curves_limits_and_bad_options_are_refused(served):
    api, collection_id, _, _ = served
    base = f"/collections/{collection_id}/exports"
    expect(api.client.get(f"{base}/landmarks.tps"), 409, "conflict", "m3 lacks t1, t2", "complete_only")
    too_many = api.client.get(f"{base}/landmarks.tps", params={"pseudo": MAX_PSEUDO + 1, "complete_only": True})
    expect(too_many, 413, "too_large", "CURVEFM_MAX_PSEUDO_LANDMARKS", str(MAX_PSEUDO))
    expect(api.client.get(f"{base}/pseudo_landmarks.csv", params={"complete_only": True}), 400, "invalid", "pseudo=N")
    expect(api.client.get(f"{base}/landmarks.tps", params={"semilandmarks": 10**6}), 422, "invalid", "semilandmarks")
    expect(api.client.get(f"{base}/landmarks.tps", params={"run": "r99"}), 404, "not_found", "r99")
    assert api.client.get(f"{base}/target.mrk.json").status_code == 422
