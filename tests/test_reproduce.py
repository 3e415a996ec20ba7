"""``curvefm reproduce --suite ci``: two real pairs, the whole pipeline, the trend the paper shows."""

import json
import os
import subprocess
import sys

import pytest

from curvefm.errors import CurvefmError
from curvefm.evaluation.reproduce import reproduce
from curvefm.evaluation.reproduce.accuracy import VARIANTS


@pytest.fixture(scope="module")
def run(shared_data, tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    command = [sys.executable, "-m", "curvefm.cli", "reproduce", "--suite", "ci", "--out", str(out / "results"),
               "--data", str(out / "store")]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    return out / "results", done


def load(results, name):
    return json.loads((results / name).read_text())


def test_every_method_variant_count_and_seed_is_recorded(run):
    results, _ = run
    accuracy = load(results, "accuracy.json")
    assert set(accuracy["summary"]) == {"faust", "cat-lion"}
    expected = {(p, v.key, c, s) for p in ("tr_reg_000->tr_reg_011", "cat-00->lion-00") for v in VARIANTS
                for c in (1, 5, 20) for s in (0, 1)}  # fmt: skip
    recorded = {(r["pair"], r["variant"], r["count"], r["seed"]) for r in accuracy["records"]}
    assert recorded == expected
    for record in accuracy["records"]:
        assert "failed" not in record, record
        assert 0 <= record["mean"] < 1 and record["mean_area"] > 0 and 0 < record["auc"] <= 1
    for by_variant in accuracy["summary"].values():
        for by_count in by_variant.values():
            for cell in by_count.values():
                assert cell["runs"] == 2 and len(cell["curve"]) == 51 and cell["curve"] == sorted(cell["curve"])


def test_more_curves_give_lower_error_and_traced_curves_stay_close_to_exact(run):
    summary = load(run[0], "accuracy.json")["summary"]
    for dataset, by_variant in summary.items():
        for variant in ("curves-traced", "curves-exact"):
            means = [by_variant[variant][str(c)]["mean"] for c in (1, 5, 20)]
            assert means[0] > means[1] > means[2], (dataset, variant, means)
        traced, exact = by_variant["curves-traced"]["20"]["mean"], by_variant["curves-exact"]["20"]["mean"]
        assert traced < 1.5 * exact, (dataset, traced, exact)


def test_timing_compares_three_solvers_that_agree(run):
    timing = load(run[0], "timing.json")
    assert [r["curves"] for r in timing["by_count"]] == [1, 10]
    assert [r["k"] for r in timing["by_k"]] == [20, 60]
    for row in timing["by_count"] + timing["by_k"]:
        for solver in ("ours", "cg", "quasi_newton"):
            assert row[solver]["ms"] > 0
        # all three minimise the same energy: the iterative ones stop near the exact maps
        assert row["cg"]["deviation"] < 1e-3 and row["quasi_newton"]["deviation"] < 1e-3
        assert row["cg"]["iterations"] > 0 and row["quasi_newton"]["iterations"] > 0
    assert all(0 < r["mean"] < 0.1 for r in timing["by_k"])


def test_plots_and_a_report_with_every_claim(run):
    results, done = run
    for name in ("accuracy_faust.png", "accuracy_cat-lion.png", "timing.png"):
        data = (results / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
    report = (results / "results.md").read_text()
    assert "![faust](accuracy_faust.png)" in report and "![timing](timing.png)" in report
    claims = load(results, "results.json")["claims"]
    assert len(claims) == 7
    for claim in claims:
        assert claim["verdict"] in ("holds", "partly holds", "does not hold")
        assert f"| {claim['claim']} | **{claim['verdict']}** |" in report
        assert claim["verdict"] in done.stdout


def test_bad_requests_are_named(tmp_path, monkeypatch):
    with pytest.raises(CurvefmError, match="unknown suite 'huge'; suites are full, ci"):
        reproduce(tmp_path, suite="huge")
    with pytest.raises(CurvefmError, match="unknown experiment"):
        reproduce(tmp_path, experiments=("speed",))
    env = os.environ | {"CURVEFM_SHARED_DATA": str(tmp_path / "nowhere")}
    done = subprocess.run([sys.executable, "-m", "curvefm.cli", "reproduce", "--out", str(tmp_path / "r")],
                          capture_output=True, text=True, env=env)  # fmt: skip
    assert done.returncode == 2 and "shared data folder not found" in done.stderr
