"""The command line, run as a user runs it."""

import json
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from support.shapes import ellipsoid

from curvefm.geometry import load_mesh, save_mesh


def curvefm(*args, data):
    return subprocess.run(
        [sys.executable, "-m", "curvefm.cli", *map(str, args), "--data", str(data)], capture_output=True, text=True
    )


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pair")
    save_mesh(ellipsoid(), folder / "source.off")
    save_mesh(ellipsoid(radii=(1.2, 0.6, 0.5)), folder / "target.obj")
    curves = {
        "curves": [
            {"source": [0, 600], "target": [0, 600]},
            {"source": [100, 900, 1100], "target": [100, 900, 1100]},
            {"source": [40, 700], "target": [40, 700], "tracer": "anisotropic"},
        ]
    }
    (folder / "curves.json").write_text(json.dumps(curves))
    return folder


def test_match_writes_maps_and_a_textured_target(pair, tmp_path):
    out = tmp_path / "out"
    run = curvefm(
        "match",
        pair / "source.off",
        pair / "target.obj",
        "--curves",
        pair / "curves.json",
        "--out",
        out,
        "--k",
        30,
        data=tmp_path / "data",
    )
    assert run.returncode == 0, run.stderr
    target = load_mesh(pair / "target.obj")
    assert np.load(out / "C_source_to_target.npy").shape == (30, 30)
    assert np.load(out / "C_target_to_source.npy").shape == (30, 30)
    to_source = np.loadtxt(out / "map_target_to_source.txt", dtype=int)
    assert to_source.shape == (target.n_vertices,) and to_source.min() >= 0 and to_source.max() < 1154
    # same connectivity, so most target vertices should map close to their own id's position on the source
    source = load_mesh(pair / "source.off")
    dist = np.linalg.norm(source.vertices[to_source] - source.vertices, axis=1)
    assert np.median(dist) < 0.2
    textured = load_mesh(out / "target_textured.obj")
    assert textured.uv is not None and textured.n_vertices == target.n_vertices
    assert np.isfinite(textured.uv).all() and np.ptp(textured.uv[:, 1]) > 0.5
    assert textured.texture_path is not None  # its material and texture lie beside it
    with zipfile.ZipFile(out / "target_textured.zip") as archive:  # the same three files, written once
        for name in ("target_textured.obj", "target_textured.mtl", "target_textured.png"):
            assert archive.read(name) == (out / name).read_bytes()


def test_basis_is_computed_once_then_found_by_match(pair, tmp_path):
    data = tmp_path / "data"
    run = curvefm("basis", pair / "source.off", "--k", 30, data=data)
    assert run.returncode == 0, run.stderr
    assert "basis: 100%" in run.stderr  # the progress bar
    stored = list((data / "bases").glob("*/laplace-beltrami-k30-*.npz"))
    assert len(stored) == 1
    written = stored[0].stat().st_mtime_ns
    run = curvefm(
        "match",
        pair / "source.off",
        pair / "source.off",
        "--curves",
        pair / "curves.json",
        "--out",
        tmp_path / "out",
        "--k",
        30,
        data=data,
    )
    assert run.returncode == 0, run.stderr
    assert "basis found in the store" in run.stderr
    assert list((data / "bases").glob("*/*.npz")) == stored and stored[0].stat().st_mtime_ns == written
    assert np.load(tmp_path / "out" / "C_source_to_target.npy").shape == (30, 30)


def test_basis_reports_bad_parameters_clearly(pair, tmp_path):
    run = curvefm("basis", pair / "source.off", "--params", '{"method": "guess"}', data=tmp_path / "data")
    assert run.returncode == 2 and "method" in run.stderr


def test_match_runs_a_baseline_method_from_the_curves_endpoints(pair, tmp_path):
    out = tmp_path / "out"
    run = curvefm(
        "match",
        pair / "source.off",
        pair / "target.obj",
        "--curves",
        pair / "curves.json",
        "--out",
        out,
        "--k",
        30,
        "--method",
        "no17",
        "--method-params",
        '{"k": 20, "spectrum": 30}',
        data=tmp_path / "data",
    )
    assert run.returncode == 0, run.stderr
    assert np.load(out / "C_source_to_target.npy").shape == (20, 20)
    to_source = np.loadtxt(out / "map_target_to_source.txt", dtype=int)
    source = load_mesh(pair / "source.off")
    assert np.median(np.linalg.norm(source.vertices[to_source] - source.vertices, axis=1)) < 0.3


@pytest.mark.parametrize(
    "options, message",
    [
        (["--method", "magic"], "unknown method 'magic'; installed methods: combined, curves, no17, obcs12"),
        (["--method", "obcs12", "--method-params", '{"k": 0}'], "bad parameters for 'obcs12': k"),
        (["--method-params", "[1"], "--method-params must be a JSON object"),
        (["--method", "obcs12", "--method-params", '{"k": 50}'], "k = 50 but the bases have only 20"),
    ],
)
def test_match_reports_bad_methods_clearly(pair, tmp_path, options, message):
    run = curvefm(
        "match",
        pair / "source.off",
        pair / "target.obj",
        "--curves",
        pair / "curves.json",
        "--out",
        tmp_path / "out",
        "--k",
        20,
        *options,
        data=tmp_path / "data",
    )
    assert run.returncode == 2, run.stderr
    assert message in run.stderr


@pytest.mark.parametrize(
    "curves, message",
    [
        ({"curves": [{"source": [0, 99999], "target": [0, 600]}]}, "waypoint 99999 is out of range"),
        ({"curves": [{"source": [0, 600], "target": [0, 600], "tracer": "magic"}]}, "unknown tracer 'magic'"),
        ({"curves": [{"source": [0, 600]}]}, "curves.0.target: Field required"),
        ({"curves": [{"source": [0, 5], "target": [0, 5], "explicit": True}]}, "not edge-connected"),
    ],
)
def test_match_reports_bad_curves_clearly(pair, tmp_path, curves, message):
    (tmp_path / "bad.json").write_text(json.dumps(curves))
    run = curvefm(
        "match",
        pair / "source.off",
        pair / "target.obj",
        "--curves",
        tmp_path / "bad.json",
        "--out",
        tmp_path / "out",
        "--k",
        20,
        data=tmp_path / "data",
    )
    assert run.returncode == 2
    assert message in run.stderr


def test_evaluate_prints_json_errors(shared_data, tmp_path):
    folder = shared_data / "nonisometric" / "pyfm_cat_lion"
    run = curvefm(
        "evaluate",
        folder / "cat-00.off",
        folder / "lion-00.off",
        "--curves",
        5,
        "--k",
        40,
        "--endpoints-on",
        "target",
        "--json",
        data=tmp_path / "data",
    )
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout)
    assert report["ground_truth"] == "lion2cat" and report["endpoints_on"] == "target"
    errors = report["errors"]["source_to_target"]
    assert 0 < errors["mean_area"] < 0.2 and len(errors["curve"]) == len(errors["radii"])


def test_evaluate_scores_a_baseline_method(shared_data, tmp_path):
    folder = shared_data / "faust"
    run = curvefm(
        "evaluate",
        folder / "tr_reg_000.off",
        folder / "tr_reg_011.off",
        "--curves",
        5,
        "--k",
        60,
        "--method",
        "obcs12",
        "--method-params",
        '{"spectrum": 60}',
        "--json",
        data=tmp_path / "data",
    )
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout)
    assert report["method"] == "obcs12" and report["ground_truth"] == "identity"
    assert 0 < report["errors"]["source_to_target"]["mean"] < 0.3
