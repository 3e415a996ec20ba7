"""Can an intrinsic figure decide the combined map's size and energy switches, instead of curve counts tuned on the
suite (50 x 50 below ``FULL_SIZE_CURVES`` = 20 curves; the curve energy alone from ``CURVES_ALONE_FROM`` = 5 curves
on strongly non-isometric pairs)?

Reads the output of ``python -m benchmarks.bench_monotone --figures`` (clicks in the UI's order on the suite or on
the held-out pairs, both directions, several seeds; per click the error of each map and the intrinsic figures) and
scores each rule over every click: the mean error, the share of clicks that made the map worse and the largest
rise. The rules:

- ``count_20``: the switches until 2026-11-28 (the whole map from 20 curves);
- ``always_full``: the whole map with the full-size weights from the first curve (for reference);
- ``length_full``: the whole map once the curves' total length resolves every one of the k frequencies
  (``resolved >= k``: half a wavelength of the k-th eigenfunction no shorter than the spacing area / length of
  curves of that total length spread evenly; derived, no constant fitted), else the prior's size;
- ``length_wavelength``: the whole map once the curves' total length on the unit-area source reaches
  ``sqrt(k / pi)``: curves of that length spread evenly lie one wavelength of the k-th eigenfunction apart (Weyl's
  law on a unit-area surface, ``lam_k ~ 4 pi k``). The factor (a wavelength, not half of one as ``length_full``
  asks) was picked after seeing the suite's FAUST runs; the held-out pairs decide;
- ``length_size``: the largest of 50 / 70 / 90 / 120 that the curves' length resolves (at least the prior's 50);
- ``fallback_from_N``: the curve energy alone for strongly non-isometric pairs from N curves on (N = 5 is the
  default), the whole map from 20 curves.

Prints one JSON object: per rule the figures on the runs given. experiments/monotone_rule.json (the suite) and
experiments/monotone_rule_held_out.json (the held-out pairs) hold them with the runs (2026-11-28, 3 seeds, 10
curves where the truth allows, pairs up to 60,000 vertices; deterministic).

    python -m benchmarks.bench_monotone --figures --pairs suite --curves 10 --seeds 3 \\
        --datasets faust faust-5k tosca cat-lion tosca-cross --max-vertices 60000 > bench.json
    python -m experiments.monotone_rule bench.json
"""

import argparse
import json
from collections.abc import Callable

import numpy as np

from benchmarks.bench_monotone import worsening
from curvefm.fmap import CURVES_ALONE_FROM, DEFAULT_K, NON_ISOMETRIC_DISTORTION

Rule = Callable[[int, dict, dict], float]  # (curves, errors of the click, figures of the click) -> error
SIZES = (50, 70, 90)


def always_full(curves: int, errors: dict, figures: dict) -> float:
    return fallback(curves, errors, figures, CURVES_ALONE_FROM) or errors["full_size"]


def length_full(curves: int, errors: dict, figures: dict) -> float:
    sized = errors["full_size"] if figures["resolved"] >= DEFAULT_K else errors["prior_size"]
    return fallback(curves, errors, figures, CURVES_ALONE_FROM) or sized


def length_wavelength(curves: int, errors: dict, figures: dict) -> float:
    sized = errors["full_size"] if figures["length"] >= np.sqrt(DEFAULT_K / np.pi) else errors["prior_size"]
    return fallback(curves, errors, figures, CURVES_ALONE_FROM) or sized


def length_size(curves: int, errors: dict, figures: dict) -> float:
    size = max([s for s in (*SIZES, DEFAULT_K) if s <= figures["resolved"]], default=SIZES[0])
    sized = {SIZES[0]: errors["prior_size"], DEFAULT_K: errors["full_size"]}.get(size) or figures[f"full_size_{size}"]
    return fallback(curves, errors, figures, CURVES_ALONE_FROM) or sized


def fallback(curves: int, errors: dict, figures: dict, start: int) -> float | None:
    """The curve energy's error where the fallback applies from ``start`` curves, else None."""
    applies = curves >= start and figures["distortion"] > NON_ISOMETRIC_DISTORTION
    return errors["curves"] if applies else None


def fallback_from(start: int) -> Rule:
    def rule(curves: int, errors: dict, figures: dict) -> float:
        return fallback(curves, errors, figures, start) or errors["prior_size" if curves < 20 else "full_size"]

    return rule


RULES: dict[str, Rule] = {
    "count_20": fallback_from(CURVES_ALONE_FROM),
    "always_full": always_full,
    "length_full": length_full,
    "length_wavelength": length_wavelength,
    "length_size": length_size,
} | {f"fallback_from_{n}": fallback_from(n) for n in (3, 4, 5, 6, 8)}


def series(run: dict, rule: Rule) -> list[float]:
    clicks = zip(run["figures"], *(run["errors"][m] for m in run["errors"]), strict=True)
    names = list(run["errors"])
    return [rule(n, dict(zip(names, values, strict=True)), figs) for n, (figs, *values) in enumerate(clicks, 1)]


def evaluate(runs: list[dict]) -> dict:
    out = {}
    for name, rule in RULES.items():
        per_run = [series(run, rule) for run in runs]
        out[name] = {
            "mean_error": round(float(np.mean([e for s in per_run for e in s])), 5),
            "mean_last": round(float(np.mean([s[-1] for s in per_run])), 5),
        } | worsening(per_run)
    return out


def by_dataset(runs: list[dict]) -> dict:
    datasets = sorted({run["dataset"] for run in runs})
    return {d: evaluate([run for run in runs if run["dataset"] == d]) for d in datasets}


def figures_at(runs: list[dict]) -> dict:
    """The intrinsic figures' range per click count, across runs: what a rule reading them sees."""
    longest = max(len(run["figures"]) for run in runs)
    out = {}
    for i in range(longest):
        at = [run["figures"][i] for run in runs if len(run["figures"]) > i]
        out[i + 1] = {key: [min(f[key] for f in at), max(f[key] for f in at)] for key in ("length", "resolved")}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bench", type=argparse.FileType(), help="bench_monotone --figures output")
    args = parser.parse_args()
    bench = json.load(args.bench)
    runs = bench["runs"]
    result = {
        "experiment": "monotone_rule",
        "machine": bench["machine"],
        "pairs": bench["pairs"],
        "error": bench["error"],
        "rules": evaluate(runs),
        "by_dataset": by_dataset(runs),
        "figures_by_click": figures_at(runs),
        "runs": runs,
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
