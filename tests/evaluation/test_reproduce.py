"""``curvefm reproduce --suite ci``: two real pairs, the whole pipeline, the trend the paper shows."""

import json
import os
import subprocess
import sys
from collections import defaultdict
from itertools import pairwise

import pytest

from curvefm.errors import CurvefmError
from curvefm.evaluation.reproduce import reproduce
from curvefm.evaluation.reproduce.accuracy import SUMMARIES, VARIANTS
from curvefm.evaluation.reproduce.datasets import DATASETS, NON_ISOMETRIC
from curvefm.evaluation.reproduce.report import INTERACTIVE_MS, NEAR_EXACT, SAME_INPUTS


@pytest.fixture(scope="module")
def run(shared_data, tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    command = [
        sys.executable,
        "-m",
        "curvefm.cli",
        "reproduce",
        "--suite",
        "ci",
        "--seeds",
        "1",
        "--out",
        str(out / "results"),
        "--data",
        str(out / "store"),
    ]
    # one curve draw of the two: 84 runs' maps converted as `curvefm match` hands them out (about 5 CPU s each)
    done = subprocess.run(command, capture_output=True, text=True, timeout=7200)
    assert done.returncode == 0, done.stderr[-3000:]
    return out / "results"


def load(results, name):
    return json.loads((results / name).read_text())


def test_every_method_variant_count_seed_side_and_direction_is_recorded(run):
    accuracy = load(run, "accuracy.json")
    summaries = [accuracy[key] for key in SUMMARIES]
    assert all(set(summary) == {"faust", "cat-lion"} for summary in summaries)
    expected = {
        (p, v.key, c, s, side, d)
        for p in ("tr_reg_000->tr_reg_011", "cat-00->lion-00")
        for v in VARIANTS
        for c in (1, 5, 20)
        for s in (0,)
        for side in ("source", "target")
        for d in ("source_to_target", "target_to_source")
    }
    recorded = {
        (r["pair"], r["variant"], r["count"], r["seed"], r["endpoints_on"], r["direction"]) for r in accuracy["records"]
    }
    assert recorded == expected and len(accuracy["records"]) == len(expected)
    for record in accuracy["records"]:
        assert "failed" not in record, record
        assert 0 <= record["mean"] < 1 and record["mean_area"] > 0 and 0 < record["auc"] <= 1
        # dense truth: at most the 1000 sampled rows, less those at a curve's end
        assert 0 < record["scored"] <= 1000 and record["convert_seconds"] > 0
    for summary in summaries:
        for by_variant in summary.values():
            for by_count in by_variant.values():
                for cell in by_count.values():
                    assert cell["runs"] == 1 and len(cell["curve"]) == 51 and cell["curve"] == sorted(cell["curve"])
    runs = defaultdict(dict)
    for r in accuracy["records"]:
        runs[(r["pair"], r["variant"], r["count"], r["seed"], r["endpoints_on"])][r["direction"]] = r
    # both maps of a run are scored, each on its own shape: their figures differ
    assert any(both["source_to_target"]["mean"] != both["target_to_source"]["mean"] for both in runs.values())
    # and the two sides are separate runs (their own curves), not one map read twice
    for both in runs.values():  # one solve and one conversion give both maps, scored at the same rows
        assert both["source_to_target"]["seconds"] == both["target_to_source"]["seconds"]
        assert both["source_to_target"]["scored"] == both["target_to_source"]["scored"]
    assert any(
        both["source_to_target"]["mean"] != runs[key[:4] + ("target",)]["source_to_target"]["mean"]
        for key, both in runs.items()
        if key[4] == "source"
    )


def test_the_curves_ends_are_not_scored(run):
    """With 20 curves a run ends at up to 40 of the pool's 40 candidates; some fall among the 1000 sampled rows and are
    dropped, on either side: had the ends been scored, every run would score all 1000."""
    records = load(run, "accuracy.json")["records"]
    for side in ("source", "target"):
        for pair in ("tr_reg_000->tr_reg_011", "cat-00->lion-00"):
            scored = [r["scored"] for r in records if (r["endpoints_on"], r["pair"], r["count"]) == (side, pair, 20)]
            assert min(scored) < 1000, (side, pair)


def test_more_curves_give_lower_error_and_traced_curves_stay_close_to_exact(run):
    summary = load(run, "accuracy.json")["summary"]
    for dataset, by_variant in summary.items():
        for variant in ("curves-traced", "curves-exact"):
            means = [by_variant[variant][str(c)]["mean"] for c in (1, 5, 20)]
            assert means[0] > means[1] > means[2], (dataset, variant, means)
        traced, exact = by_variant["curves-traced"]["20"]["mean"], by_variant["curves-exact"]["20"]["mean"]
        assert traced < 1.5 * exact, (dataset, traced, exact)


def test_timing_compares_three_solvers_that_agree(run):
    timing = load(run, "timing.json")
    assert [r["curves"] for r in timing["by_count"]] == [1, 10]
    assert [r["k"] for r in timing["by_k"]] == [20, 60]
    for row in timing["by_count"] + timing["by_k"]:
        # all three minimise the same energy: the iterative ones stop near the exact maps
        assert row["cg"]["deviation"] < 1e-3 and row["quasi_newton"]["deviation"] < 1e-3
        assert row["cg"]["iterations"] > 0 and row["quasi_newton"]["iterations"] > 0
    assert all(0 < r["mean"] < 0.1 for r in timing["by_k"])


def test_plots_and_a_report_with_every_claim(run):
    results = run
    for name in ("accuracy_faust.png", "accuracy_cat-lion.png", "timing.png"):
        data = (results / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
    report = (results / "results.md").read_text()
    assert "![faust](accuracy_faust.png)" in report and "![timing](timing.png)" in report
    assert report.count("Target -> source, endpoints chosen on the target:") == 2
    assert "## Which method wins: target -> source, endpoints chosen on the target" in report
    assert "## Both maps of every run" in report and "pointwise maps `curvefm match` hands out" in report
    assert "This run is a subset of the full suite: 2 of its 12 pairs" in report
    claims = load(results, "results.json")["claims"]
    expected = expected_verdicts(load(results, "accuracy.json")["summary"], load(results, "timing.json"))
    assert len(claims) == len(expected) == 8
    for claim in claims:
        (start,) = [start for start in expected if claim["claim"].startswith(start)]
        assert claim["verdict"] == expected[start], (claim, expected[start])
        assert f"| {claim['claim']} | **{claim['verdict']}** |" in report


def expected_verdicts(summary: dict, timing: dict) -> dict[str, str]:
    """Each claim's verdict worked out here from the recorded numbers, by the first words of the claim: it
    holds where every comparison behind it does, partly where some do."""

    def mean(dataset, variant, count):
        return summary[dataset][variant][str(count)]["mean"]

    def counts(dataset, variant):
        return sorted(int(c) for c in summary[dataset].get(variant, {}))

    ours = "curves-traced"
    checks = {
        "One curve already beats": [mean(d, ours, 1) < mean(d, "obcs12-wks", 1) for d in summary],
        "... even when the descriptors": [mean(d, ours, 1) < mean(d, "obcs12", 1) for d in summary],
        "Accuracy rises": [
            all(mean(d, ours, a) > mean(d, ours, b) for a, b in pairwise(counts(d, ours))) for d in summary
        ],
        "Traced curves are almost as good": [
            mean(d, ours, c) <= NEAR_EXACT * mean(d, "curves-exact", c)
            for d in summary
            for c in counts(d, "curves-exact")
            if c >= 5
        ],
        "Curve constraints beat NO17": [
            mean(d, ours, c) < mean(d, "no17", c) for d in summary if d in NON_ISOMETRIC for c in counts(d, ours)
        ],
        "Curves as constraints beat": [
            mean(d, ours, c) < mean(d, "no17-curves", c) for d in summary for c in counts(d, "no17-curves")
        ],
        "The default (combined) is at least as good": [
            mean(d, "combined-traced", c) <= min(mean(d, v, c) for v in ("curves-traced", "obcs12", "no17"))
            for d in summary
            for c in counts(d, "combined-traced")
        ],
        "The solver is interactive": [
            all(row["ours"]["ms"] <= INTERACTIVE_MS for row in timing["by_count"]),
            all(row["quasi_newton"]["ms"] > INTERACTIVE_MS for row in timing["by_count"]),
        ],
    }
    return {
        start: "holds" if passed and all(passed) else "partly holds" if any(passed) else "does not hold"
        for start, passed in checks.items()
    }


def test_bad_requests_are_named(tmp_path, monkeypatch):
    with pytest.raises(CurvefmError, match="unknown suite 'huge'; suites are full, ci"):
        reproduce(tmp_path, suite="huge")
    with pytest.raises(CurvefmError, match="unknown experiment"):
        reproduce(tmp_path, experiments=("speed",))
    with pytest.raises(CurvefmError, match="at least one seed is needed, not 0"):
        reproduce(tmp_path, suite="ci", seeds=0)
    env = os.environ | {"CURVEFM_SHARED_DATA": str(tmp_path / "nowhere")}
    done = subprocess.run(
        [sys.executable, "-m", "curvefm.cli", "reproduce", "--out", str(tmp_path / "r")],
        capture_output=True,
        text=True,
        env=env,
    )
    assert done.returncode == 2 and "shared data folder not found" in done.stderr


def test_the_report_names_the_winner_of_every_dataset_and_curve_count(run):
    report = (run / "results.md").read_text()
    labels = {v.key: v.label for v in VARIANTS}
    for dataset, by_variant in load(run, "accuracy.json")["summary"].items():
        for count in (1, 5, 20):
            means = {v: by_variant[v][str(count)]["mean"] for v in SAME_INPUTS}
            best = min(means, key=means.get)
            assert f"| {DATASETS[dataset]} | {count} | {labels[best]} | {means[best]:.3f} |" in report
