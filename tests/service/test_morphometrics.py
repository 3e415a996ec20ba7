"""Morphometrics formats over HTTP on two FAUST scans (ground truth: the same vertex id): every landmark export of
a session read back by the readers of tests/support (written from the formats' specifications) and compared with
the session's curves; Slicer markups posted to seed curves, with their snapping distances; bad files and points too
far from the mesh refused with a 4xx naming them."""

from __future__ import annotations

import numpy as np
import pytest
from support.errors import expect
from support.morphometrics import fcsv_file, mrk_file, read_curveslide, read_fcsv, read_morphologika, read_mrk, read_tps

from curvefm.client import Client
from curvefm.geometry import load_mesh

K = 20
CURVES = [{"source": [412, 5891], "target": [412, 5891]}, {"source": [3057, 6617], "target": [3057, 6617]}]
NAME = "faust 000 -> 011"
SEMILANDMARKS, PSEUDO = 10, 12
LANDMARK_EXPORTS = {
    "source.mrk.json": "application/json",
    "target.mrk.json": "application/json",
    "source.fcsv": "text/csv",
    "target.fcsv": "text/csv",
    "landmarks.tps": "text/plain",
    "morphologika.txt": "text/plain",
    "curveslide.csv": "text/csv",
}


@pytest.fixture(scope="module")
def served(module_processes, shared_data, tmp_path_factory):
    api = module_processes.api(tmp_path_factory.mktemp("morphometrics") / "data")
    files = [shared_data / "faust" / f"tr_reg_{n}.off" for n in ("000", "011")]
    shapes = [api.upload(path) for path in files]
    for shape_id in shapes:
        job = api.client.post(f"/shapes/{shape_id}/bases", json={"k": K}).raise_for_status().json()
        assert api.wait_job(job["id"])["state"] == "finished"
    body = {"source": shapes[0], "target": shapes[1], "k": K, "name": NAME}
    session_id = api.client.post("/sessions", json=body).raise_for_status().json()["id"]
    for curve in CURVES:
        api.client.post(f"/sessions/{session_id}/curves", json=curve).raise_for_status()
    return api, session_id, shapes, [load_mesh(path) for path in files]


def downloaded(api, session_id: str, export: str, **params) -> str:
    answer = api.client.get(f"/sessions/{session_id}/exports/{export}", params=params).raise_for_status()
    revision = api.client.get(f"/sessions/{session_id}").json()["revision"]
    assert answer.headers["content-type"].startswith(LANDMARK_EXPORTS[export])
    assert answer.headers["x-revision"] == str(revision)
    disposition = f'attachment; filename="faust-000-011_{session_id}_live_r{revision}_{export}"'
    assert answer.headers["content-disposition"] == disposition
    return answer.text


def test_every_landmark_export_reads_back_as_the_sessions_curves(served):
    api, session_id, _, meshes = served
    files = {
        name: downloaded(api, session_id, name, semilandmarks=SEMILANDMARKS, pseudo=PSEUDO) for name in LANDMARK_EXPORTS
    }
    record = api.client.get(f"/sessions/{session_id}").json()
    size = len(record["curves"]) * (SEMILANDMARKS + 2) + PSEUDO
    tps = read_tps(files["landmarks.tps"])
    names, raw = read_morphologika(files["morphologika.txt"])
    assert names == [name for name, _ in tps] == ["tr_reg_000", "tr_reg_011"] and raw.shape == (2, size, 3)
    assert len(read_curveslide(files["curveslide.csv"])) == len(record["curves"]) * SEMILANDMARKS
    for side, (role, mesh) in enumerate(zip(("source", "target"), meshes, strict=True)):
        _, labels, points = read_fcsv(files[f"{role}.fcsv"])
        assert np.allclose(tps[side][1], points, atol=1e-6) and np.allclose(raw[side], points, atol=1e-6)
        curves = [m for m in read_mrk(files[f"{role}.mrk.json"]) if m["type"] == "Curve"]
        assert [m["name"] for m in curves] == [c["id"] for c in record["curves"]]
        for markup, curve in zip(curves, record["curves"], strict=True):
            path = curve[f"path_{role}"]
            assert len(markup["points"]) == SEMILANDMARKS + 2 and markup["labels"][0] == f"{curve['id']}-start"
            assert np.allclose(markup["points"][[0, -1]], mesh.vertices[[path[0], path[-1]]], atol=1e-6)
            assert np.allclose(points[[labels.index(label) for label in markup["labels"]]], markup["points"], atol=1e-6)
    on_M, on_N = (read_fcsv(files[f"{role}.fcsv"])[2][-PSEUDO:] for role in ("source", "target"))
    x = [int(np.argmin(np.linalg.norm(meshes[0].vertices - p, axis=1))) for p in on_M]
    y = [int(np.argmin(np.linalg.norm(meshes[1].vertices - p, axis=1))) for p in on_N]
    assert np.allclose(meshes[1].vertices[y], on_N, atol=1e-6) and len(set(x)) == PSEUDO
    errors = np.linalg.norm(meshes[1].vertices[y] - meshes[1].vertices[x], axis=1) / np.sqrt(meshes[1].area)
    assert np.median(errors) < 0.1, errors  # near the ground truth: the live map carried them


def test_a_refinements_landmarks_carry_its_pseudo_landmarks_by_its_pointwise_map(served):
    api, session_id, _, meshes = served
    with Client(api.url, token=api.token) as client:
        r = client.open_session(session_id).refine("nearest-neighbor").wait(progress=False)
    base = f"/sessions/{session_id}/exports"
    answer = api.client.get(f"{base}/target.fcsv", params={"refinement": r.job_id, "pseudo": PSEUDO})
    assert answer.status_code == 200, answer.text
    name = f"faust-000-011_{session_id}_nearest-neighbor_r{r.revision}_target.fcsv"
    assert answer.headers["content-disposition"] == f'attachment; filename="{name}"'
    source = api.client.get(f"{base}/source.fcsv", params={"refinement": r.job_id, "pseudo": PSEUDO}).text
    on_M, on_N = read_fcsv(source)[2][-PSEUDO:], read_fcsv(answer.text)[2][-PSEUDO:]
    x = [int(np.argmin(np.linalg.norm(meshes[0].vertices - p, axis=1))) for p in on_M]
    assert np.allclose(meshes[1].vertices[r.map_source_to_target[x]], on_N, atol=1e-6)
    expect(api.client.get(f"{base}/maps.mat", params={"refinement": r.job_id}), 400, "invalid", "landmark exports")
    expect(api.client.get(f"{base}/target.fcsv", params={"refinement": "nope"}), 404, "not_found", "nope")


def test_the_client_downloads_landmarks_and_imports_them_back(served, tmp_path):
    """The exported markups, posted back, make the same curves again: their control points are on the paths."""
    api, session_id, _, _ = served
    with Client(api.url, token=api.token) as client:
        session = client.open_session(session_id)
        before = session.curves
        files = [
            session.landmarks(f"{side}.mrk.json", tmp_path / f"{side}.mrk.json", 5) for side in ("source", "target")
        ]
        answer = session.import_markups(*files, if_revision=session.refresh()["revision"])
    assert answer["names"] == [c.id for c in before] and answer["unpaired"] == []
    for added, curve in zip(answer["curves"], before, strict=True):
        assert added["path_source"][0] == curve.path_source[0] and added["path_target"][-1] == curve.path_target[-1]
    ends = [p for p in answer["points"] if p["label"].endswith(("-start", "-end"))]
    assert ends and all(p["distance"] == 0.0 for p in ends)


def test_export_options_out_of_bounds_and_sessions_without_curves_are_refused(served):
    api, session_id, shapes, _ = served
    base = f"/sessions/{session_id}/exports"
    expect(api.client.get(f"{base}/landmarks.tps", params={"semilandmarks": -1}), 422, "invalid", "semilandmarks")
    expect(api.client.get(f"{base}/landmarks.tps", params={"pseudo": 10**6}), 422, "invalid", "pseudo")
    empty = api.client.post("/sessions", json={"source": shapes[0], "target": shapes[1], "k": K}).json()["id"]
    expect(api.client.get(f"/sessions/{empty}/exports/source.mrk.json"), 400, "invalid", "has no curves")
    assert api.client.get(f"/sessions/{empty}/exports/source.fcsv", params={"pseudo": 5}).status_code == 200


def at(mesh, vertex: int, offset: float = 0.0) -> np.ndarray:
    return mesh.vertices[vertex] + offset * np.sqrt(mesh.area) * np.array([0.0, 0.6, 0.8])


def test_posted_markups_seed_curves_at_the_nearest_vertices_with_their_distances(served):
    api, session_id, _, (M, N) = served
    revision = api.client.get(f"/sessions/{session_id}").json()["revision"]
    ids, landmarks = [5000, 5200, 5400], ["nose", "chin"]
    source = mrk_file(
        [
            ("Curve", "brow", ["a", "b", "c"], np.array([at(M, v, 0.003) for v in ids])),
            ("Fiducial", "F", landmarks, np.array([at(M, 2000), at(M, 2500)])),
        ],
        system="RAS",
    )
    target = mrk_file(
        [
            ("Curve", "brow", ["a", "b", "c"], np.array([at(N, v) for v in ids])),
            ("Fiducial", "F", [*landmarks, "ear"], np.array([at(N, 2000), at(N, 2500), at(N, 10)])),
        ]
    )
    answer = api.client.post(
        f"/sessions/{session_id}/markups",
        files={"source": ("s.mrk.json", source), "target": ("t.mrk.json", target)},
        params={"join_landmarks": True},
        headers={"If-Match": f'"{revision}"'},
    )
    assert answer.status_code == 201, answer.text
    body = answer.json()
    assert body["names"] == ["brow", "nose-chin"] and body["unpaired"] == ["landmark 'ear'"]
    assert [(c["spec"]["source"], c["spec"]["target"]) for c in body["curves"]] == [(ids, ids), ([2000, 2500],) * 2]
    assert [c["path_source"][0] for c in body["curves"]] == [5000, 2000]
    assert [c["path_target"][-1] for c in body["curves"]] == [5400, 2500]
    assert body["map"]["revision"] == revision + 2
    snapped = {(p["side"], p["markup"], p["label"]): p for p in body["points"]}
    assert snapped["source", "brow", "b"]["vertex"] == 5200
    assert snapped["source", "brow", "b"]["relative_distance"] == pytest.approx(0.003, rel=1e-6)
    assert (
        snapped["target", "landmarks", "chin"]["distance"] == 0.0
        and snapped["target", "landmarks", "chin"]["file"] == "t.mrk.json"
    )
    stored = api.client.get(f"/sessions/{session_id}").json()
    assert [c["id"] for c in stored["curves"][-2:]] == [c["id"] for c in body["curves"]]


def test_fcsv_landmarks_pair_by_label(served):
    api, session_id, _, (M, N) = served
    labels = ["L1", "L2", "L3"]
    files = {
        side: (f"{side}.fcsv", fcsv_file(labels, np.array([at(mesh, v, 0.001) for v in (100, 200, 300)]), system))
        for side, mesh, system in (("source", M, "RAS"), ("target", N, "LPS"))
    }
    answer = api.client.post(f"/sessions/{session_id}/markups", files=files, params={"join_landmarks": True})
    assert answer.status_code == 201, answer.text
    assert [c["spec"]["source"] for c in answer.json()["curves"]] == [[100, 200], [200, 300]]
    assert all(p["relative_distance"] == pytest.approx(0.001, rel=1e-6) for p in answer.json()["points"])


def test_bad_markups_are_refused_by_name_and_change_nothing(served):
    api, session_id, _, (M, N) = served
    revision = api.client.get(f"/sessions/{session_id}").json()["revision"]
    url = f"/sessions/{session_id}/markups"
    far = mrk_file([("Curve", "chin", ["from", "to"], np.array([at(M, 100), at(M, 900, 0.4)]))])
    near = mrk_file([("Curve", "chin", ["from", "to"], np.array([at(N, 100), at(N, 900)]))])
    expect(
        api.client.post(url, files={"source": ("s.mrk.json", far), "target": ("t.mrk.json", near)}),
        400,
        "invalid",
        "source file s.mrk.json: point 'to' of 'chin'",
        "CURVEFM_MARKUP_SNAP_TOLERANCE",
    )
    expect(
        api.client.post(url, files={"source": ("s.mrk.json", b"{nope"), "target": ("t.mrk.json", near)}),
        400,
        "invalid",
        "s.mrk.json",
    )
    expect(
        api.client.post(url, files={"source": ("s.bin", b"\xff\xfe\x00"), "target": ("t.mrk.json", near)}),
        400,
        "invalid",
        "not a text file",
    )
    two = mrk_file(
        [
            ("Curve", "x", ["a", "b"], np.array([at(M, 1), at(M, 50)])),
            ("Curve", "y", ["a", "b"], np.array([at(M, 2), at(M, 60)])),
        ]
    )
    expect(
        api.client.post(url, files={"source": ("s.mrk.json", two), "target": ("t.mrk.json", near)}),
        400,
        "invalid",
        "2 curves",
        "1",
    )
    expect(api.client.post(url, files={"source": ("s.mrk.json", near)}), 422, "invalid", "target")
    empty = mrk_file([("Curve", "chin", [], np.zeros((0, 3)))])
    expect(
        api.client.post(url, files={"source": ("s.mrk.json", empty), "target": ("t.mrk.json", near)}),
        400,
        "invalid",
        "curve 'chin' has 0 points on the source",
    )
    long_M, long_N = (
        mrk_file([("Curve", "chin", [str(i) for i in range(101)], mesh.vertices[:5050:50])]) for mesh in (M, N)
    )
    expect(
        api.client.post(url, files={"source": ("s.mrk.json", long_M), "target": ("t.mrk.json", long_N)}),
        413,
        "too_large",
        "101 waypoints on the source of curve 'chin'",
        "MAX_WAYPOINTS",
    )
    stale = api.client.post(
        url, files={"source": ("s.mrk.json", near), "target": ("t.mrk.json", near)}, headers={"If-Match": '"1"'}
    )
    assert stale.status_code == 409, stale.text
    assert api.client.get(f"/sessions/{session_id}").json()["revision"] == revision
