"""Morphometrics formats from the command line, on two FAUST scans (same vertex ids: the ground truth is the
identity): ``curvefm export`` read back by readers written from the formats' specifications (tests/support) and
compared with the session's curves and maps; ``curvefm import-markups`` seeding curves from Slicer files."""

from __future__ import annotations

import numpy as np
import pytest
from support.morphometrics import (
    fcsv_file,
    mrk_file,
    read_curveslide,
    read_fcsv,
    read_morphologika,
    read_mrk,
    read_tps,
)

from curvefm.cli import _Collections, main
from curvefm.geometry import load_mesh
from curvefm.records.sessions import sessions_of
from curvefm.session import CurveSpec, LiveSessions, SessionCreate, SessionEditor
from curvefm.store import Store

K = 20
CURVES = [(412, 5891), (3057, 6617), (1000, 4000)]  # ground-truth vertex pairs: the same id on both scans
SEMILANDMARKS = 20
PSEUDO = 30


@pytest.fixture(scope="module")
def lab(shared_data, tmp_path_factory):
    """A data directory with FAUST 000 -> 011 and a session of three curves between ground-truth vertices."""
    data = tmp_path_factory.mktemp("morphometrics") / "data"
    store = Store(data)
    meshes = [load_mesh(shared_data / "faust" / f"tr_reg_{n}.off") for n in ("000", "011")]
    for mesh in meshes:
        store.put_mesh(mesh)
        store.ensure_basis(mesh, K)
    editor = editor_on(data)
    record = editor.create(SessionCreate(source=meshes[0].content_hash, target=meshes[1].content_hash, k=K))
    for a, b in CURVES:
        editor.add_curve(record.id, CurveSpec(source=[a, b], target=[a, b]))
    return data, record.id, meshes


def editor_on(data) -> SessionEditor:
    records = sessions_of(Store(data))
    return SessionEditor(records, LiveSessions(Store(data), records))


@pytest.fixture(scope="module")
def exported(lab, tmp_path_factory):
    data, session_id, _ = lab
    out = tmp_path_factory.mktemp("exported")
    formats = ["mrk", "fcsv", "tps", "morphologika"]
    options = ["--semilandmarks", str(SEMILANDMARKS), "--pseudo", str(PSEUDO), "--out", str(out)]
    assert main(["export", session_id, "--data", str(data), "--format", *formats, *options]) == 0
    return {path.name: path.read_text() for path in out.iterdir()}


def arc_fraction(polyline: np.ndarray, point: np.ndarray) -> tuple[float, float]:
    """Where ``point`` is along ``polyline`` (fraction of its length) and how far from it."""
    lengths = np.linalg.norm(np.diff(polyline, axis=0), axis=1)
    best = (np.inf, 0.0)
    for i, (a, b) in enumerate(zip(polyline[:-1], polyline[1:], strict=True)):
        t = float(np.clip(np.dot(point - a, b - a) / max(np.dot(b - a, b - a), 1e-300), 0, 1))
        distance = float(np.linalg.norm(a + t * (b - a) - point))
        if distance < best[0]:
            best = (distance, (lengths[:i].sum() + t * lengths[i]) / lengths.sum())
    return best[1], best[0]


def test_the_slicer_markups_hold_each_curve_resampled_along_its_traced_path(lab, exported):
    data, session_id, meshes = lab
    record = editor_on(data).record(session_id)
    for side, mesh, name in ((0, meshes[0], "source.mrk.json"), (1, meshes[1], "target.mrk.json")):
        markups = read_mrk(exported[name])
        curves = [m for m in markups if m["type"] == "Curve"]
        assert [m["name"] for m in curves] == [c.id for c in record.curves]
        assert all(m["system"] == "LPS" for m in markups)
        for markup, stored in zip(curves, record.curves, strict=True):
            path = np.asarray(stored.path_target if side else stored.path_source)
            polyline = mesh.vertices[mesh.internal_ids(path)]
            points = markup["points"]
            assert len(points) == SEMILANDMARKS + 2
            assert np.allclose(points[0], polyline[0], atol=1e-6) and np.allclose(points[-1], polyline[-1], atol=1e-6)
            where = [arc_fraction(polyline, p) for p in points]
            assert max(distance for _, distance in where) < 1e-6  # on the traced path's edges: on the surface
            assert np.allclose([f for f, _ in where], np.linspace(0, 1, SEMILANDMARKS + 2), atol=1e-6)
        landmarks, pseudo = (m for m in markups if m["type"] == "Fiducial")
        expected_ends = [(c.path_target if side else c.path_source) for c in record.curves]
        ends = mesh.vertices[mesh.internal_ids([v for p in expected_ends for v in (p[0], p[-1])])]
        assert np.allclose(landmarks["points"], ends, atol=1e-6)
        assert pseudo["name"] == "pseudo-landmarks" and len(pseudo["points"]) == PSEUDO


def test_tps_morphologika_and_fcsv_hold_the_same_configuration_in_the_same_order(exported):
    tps = read_tps(exported["landmarks.tps"])
    names, raw = read_morphologika(exported["morphologika.txt"])
    assert [name for name, _ in tps] == ["tr_reg_000", "tr_reg_011"] and names == ["tr_reg_000", "tr_reg_011"]
    size = len(CURVES) * (2 + SEMILANDMARKS) + PSEUDO
    assert raw.shape == (2, size, 3)
    for side, file in enumerate(("source.fcsv", "target.fcsv")):
        header, labels, points = read_fcsv(exported[file])
        assert header["CoordinateSystem"] == "LPS" and header["Markups fiducial file version"] == "4.11"
        assert np.allclose(tps[side][1], points, atol=1e-6) and np.allclose(raw[side], points, atol=1e-6)
        curve_points = [m for m in read_mrk(exported[file.replace("fcsv", "mrk.json")]) if m["type"] == "Curve"]
        for markup in curve_points:  # each curve's control points are the fcsv's points of the same labels
            at = [labels.index(label) for label in markup["labels"]]
            assert np.allclose(points[at], markup["points"], atol=1e-6)


def test_curveslide_slides_each_semilandmark_between_its_neighbours_on_its_curve(exported):
    _, labels, _ = read_fcsv(exported["source.fcsv"])
    rows = read_curveslide(exported["curveslide.csv"])
    assert len(rows) == len(CURVES) * SEMILANDMARKS
    assert len({slider for _, slider, _ in rows}) == len(rows)
    for before, slider, after in rows:
        curve, _, step = labels[slider - 1].rpartition("-s")
        j = int(step)
        assert labels[before - 1] == (f"{curve}-s{j - 1}" if j > 1 else f"{curve}-start")
        assert labels[after - 1] == (f"{curve}-s{j + 1}" if j < SEMILANDMARKS else f"{curve}-end")


def test_the_pseudo_landmarks_are_source_vertices_carried_by_the_live_map(lab, exported):
    """Each pseudo-landmark's target vertex is the one the live maps' spectral embeddings put nearest (computed here
    in float64 by brute force), and near its ground truth (the same vertex id on FAUST)."""
    data, session_id, meshes = lab
    editor = editor_on(data)
    C_MN, C_NM, _ = editor.maps(session_id)
    with editor.live.using(session_id) as live:
        Phi, Psi = live.solver.basis_M.evecs, live.solver.basis_N.evecs
    (k_N, k_M) = C_MN.shape
    Phi, Psi = Phi[:, :k_M], Psi[:, :k_N]
    on_M, on_N = read_fcsv(exported["source.fcsv"])[2][-PSEUDO:], read_fcsv(exported["target.fcsv"])[2][-PSEUDO:]
    x = [int(np.argmin(np.linalg.norm(meshes[0].vertices - p, axis=1))) for p in on_M]
    y = [int(np.argmin(np.linalg.norm(meshes[1].vertices - p, axis=1))) for p in on_N]
    assert np.allclose(meshes[0].vertices[x], on_M, atol=1e-6) and np.allclose(meshes[1].vertices[y], on_N, atol=1e-6)
    assert len(set(x)) == PSEUDO
    embedded_N = np.hstack([Psi, Psi @ C_NM.T])  # y: (Psi[y], C_NM Psi[y])
    embedded_M = np.hstack([Phi[x] @ C_MN.T, Phi[x]])  # x: (C_MN Phi[x], Phi[x])
    costs = np.linalg.norm(embedded_N[None, :, :] - embedded_M[:, None, :], axis=2)
    assert np.all(costs[np.arange(PSEUDO), y] <= costs.min(axis=1) + 1e-4)
    errors = np.linalg.norm(meshes[1].vertices[y] - meshes[1].vertices[x], axis=1) / np.sqrt(meshes[1].area)
    assert np.median(errors) < 0.1, errors


def test_a_refinements_landmarks_from_the_command_line(lab, tmp_path):
    """``--refinement JOB``: the pseudo-landmarks go where the job's pointwise map sends them."""
    data, session_id, meshes = lab
    jobs = _Collections(str(data))
    job_id = jobs.refine(jobs.sessions.record(session_id), "nearest-neighbor", {})
    p2p = np.load(data / "results" / job_id / "p2p_source_to_target.npy")
    options = ["--format", "fcsv", "--pseudo", "10", "--refinement", job_id, "--out", str(tmp_path)]
    assert main(["export", session_id, "--data", str(data), *options]) == 0
    on_M, on_N = (read_fcsv((tmp_path / f"{side}.fcsv").read_text())[2][-10:] for side in ("source", "target"))
    x = [int(np.argmin(np.linalg.norm(meshes[0].vertices - p, axis=1))) for p in on_M]
    assert np.allclose(meshes[1].vertices[p2p[x]], on_N, atol=1e-6)
    assert main(["export", session_id, "--data", str(data), "--refinement", "nope", "--out", str(tmp_path)]) == 2


def vertex_at(mesh, vertex: int, offset: float = 0.0) -> np.ndarray:
    return mesh.vertices[mesh.internal_ids([vertex])[0]] + offset * np.sqrt(mesh.area) * np.array([0.6, 0.0, 0.8])


def test_markups_from_slicer_seed_curves_at_their_snapped_vertices(lab, tmp_path, capsys):
    data, session_id, meshes = lab
    before = len(editor_on(data).record(session_id).curves)
    ids = [5000, 5200, 5400]
    source = mrk_file(
        [("Curve", "brow", ["a", "b", "c"], np.array([vertex_at(meshes[0], v, 0.002) for v in ids]))], system="RAS"
    )
    target = mrk_file([("Curve", "brow", ["a", "b", "c"], np.array([vertex_at(meshes[1], v) for v in ids]))])
    (tmp_path / "s.mrk.json").write_bytes(source)
    (tmp_path / "t.mrk.json").write_bytes(target)
    landmarks = [2000, 2500, 3000]
    for name, mesh in (("s.fcsv", meshes[0]), ("t.fcsv", meshes[1])):
        points = np.array([vertex_at(mesh, v, 0.001) for v in landmarks])
        (tmp_path / name).write_bytes(
            fcsv_file(["L1", "L2", "L3"], points, system="RAS" if name == "s.fcsv" else "LPS")
        )
    files = [str(tmp_path / f) for f in ("s.mrk.json", "t.mrk.json")]
    assert main(["import-markups", session_id, *files, "--data", str(data)]) == 0
    fcsvs = [str(tmp_path / f) for f in ("s.fcsv", "t.fcsv")]
    assert main(["import-markups", session_id, *fcsvs, "--data", str(data), "--join-landmarks"]) == 0
    printed = capsys.readouterr().out
    assert "source brow 'a': vertex 5000, " in printed and "(0.002 sqrt(area))" in printed
    assert "target landmarks 'L3': vertex 3000, " in printed and "(0.001 sqrt(area))" in printed
    added = editor_on(data).record(session_id).curves[before:]
    assert [(c.spec.source, c.spec.target) for c in added] == [
        (ids, ids),
        ([2000, 2500], [2000, 2500]),
        ([2500, 3000], [2500, 3000]),
    ]
    for curve in added:
        assert curve.path_source[0] == curve.spec.source[0] and curve.path_source[-1] == curve.spec.source[-1]
        assert curve.path_target[-1] == curve.spec.target[-1]


def test_a_point_too_far_from_the_mesh_is_refused_by_name(lab, tmp_path, capsys):
    data, session_id, meshes = lab
    before = editor_on(data).record(session_id).revision
    far = np.array([vertex_at(meshes[0], 100), vertex_at(meshes[0], 900, 0.3)])
    (tmp_path / "s.mrk.json").write_bytes(mrk_file([("Curve", "chin", ["from", "to"], far)]))
    near = np.array([vertex_at(meshes[1], 100), vertex_at(meshes[1], 900)])
    (tmp_path / "t.mrk.json").write_bytes(mrk_file([("Curve", "chin", ["from", "to"], near)]))
    files = [str(tmp_path / f) for f in ("s.mrk.json", "t.mrk.json")]
    assert main(["import-markups", session_id, *files, "--data", str(data)]) == 2
    error = capsys.readouterr().err
    distance = np.linalg.norm(meshes[0].vertices - far[1], axis=1).min()
    assert distance / np.sqrt(meshes[0].area) > 0.05
    assert f"source file s.mrk.json: point 'to' of 'chin' at {[round(v, 6) for v in far[1].tolist()]}" in error
    assert f"is {distance:.6g} from the nearest vertex of mesh 'tr_reg_000'" in error
    assert "more than the tolerance 0.05 sqrt(area) (--tolerance)" in error
    assert editor_on(data).record(session_id).revision == before
