"""``curvefm reproduce``: the paper's Section 5 on the shapes of the shared data folder.

Two experiments, each writing a JSON table and PNG plots into the output folder, then a Markdown report
that states for each of the paper's claims whether it holds on our data:

* ``accuracy`` (:mod:`curvefm.evaluation.reproduce.accuracy`): Figures 10/11, error against the number of curves,
  exact vs traced curves, against the OBCS12 and NO17 baselines;
* ``timing`` (:mod:`curvefm.evaluation.reproduce.timing`): Figures 13/14, update time of our solver, the paper's CG and
  L-BFGS, and time and accuracy against the basis size.

Suites (:mod:`curvefm.evaluation.reproduce.datasets`): ``full`` (12 pairs, 1-20 curves, 3 seeds) and ``ci`` (2 pairs);
``seeds`` draws fewer (or more) curve subsets per pair and count than the suite does.
"""

from __future__ import annotations

import json
import os
import platform
import time
from collections.abc import Callable
from dataclasses import replace
from datetime import date
from pathlib import Path
from typing import Any

from curvefm.errors import InvalidInput
from curvefm.evaluation.ground_truth import shared_data_dir
from curvefm.evaluation.reproduce.accuracy import run_accuracy
from curvefm.evaluation.reproduce.datasets import DATASETS, SUITES
from curvefm.evaluation.reproduce.plots import plot_accuracy, plot_timing, require_matplotlib
from curvefm.evaluation.reproduce.report import check_claims, write_report
from curvefm.evaluation.reproduce.timing import run_timing
from curvefm.progress import Progress, no_progress
from curvefm.store import Store

EXPERIMENTS = ("accuracy", "timing")
THREAD_SETTINGS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "CURVEFM_SEARCH_THREADS")
"""Environment variables that change the timings (not the errors): the report names those a run was given."""


def reproduce(
    out: str | Path,
    suite: str = "full",
    experiments: tuple[str, ...] = EXPERIMENTS,
    store: Store | None = None,
    report: str | Path | None = None,
    command: str = "curvefm reproduce",
    progress_for: Callable[[str], Progress] = lambda name: no_progress,
    seeds: int | None = None,
) -> dict[str, Any]:
    """Run the experiments, write ``accuracy.json``, ``timing.json``, the plots and the report
    (``report`` or ``OUT/results.md``); return everything as one dict. ``seeds``: curve draws per pair and count,
    else the suite's."""
    if suite not in SUITES:
        raise InvalidInput(f"unknown suite '{suite}'; suites are {', '.join(SUITES)}")
    unknown = [e for e in experiments if e not in EXPERIMENTS]
    if unknown or not experiments:
        raise InvalidInput(f"unknown experiment {unknown or experiments!r}; experiments are {', '.join(EXPERIMENTS)}")
    require_matplotlib()
    if seeds is not None and seeds < 1:
        raise InvalidInput(f"at least one seed is needed, not {seeds}")
    chosen = SUITES[suite] if seeds is None else replace(SUITES[suite], seeds=seeds)
    data, store = shared_data_dir(), store or Store()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    started, load = time.perf_counter(), os.getloadavg()[0]
    results: dict[str, Any] = {}
    figures: dict[str, Path] = {}
    if "accuracy" in experiments:
        results["accuracy"] = run_accuracy(data, chosen, store, progress_for("accuracy"))
        _write_json(out / "accuracy.json", results["accuracy"])
        for dataset, summary in results["accuracy"]["summary"].items():
            figures[dataset] = plot_accuracy(dataset, DATASETS[dataset], summary, out / f"accuracy_{dataset}.png")
    if "timing" in experiments:
        results["timing"] = run_timing(data, chosen, store, progress_for("timing"))
        _write_json(out / "timing.json", results["timing"])
        figures["timing"] = plot_timing(results["timing"], out / "timing.png")
    results["claims"] = check_claims(results.get("accuracy"), results.get("timing"))
    results["meta"] = {
        "command": command,
        "suite": suite,
        "seeds": chosen.seeds,
        "date": date.today().isoformat(),
        "machine": machine(),
        "seconds": time.perf_counter() - started,
        "load": [load, os.getloadavg()[0]],
        "environment": {name: os.environ[name] for name in THREAD_SETTINGS if name in os.environ},
        "json": str(out / "results.json"),
    }
    _write_json(out / "results.json", {"meta": results["meta"], "claims": results["claims"]})
    results["report"] = str(write_report(Path(report) if report else out / "results.md", results, figures))
    return results


def machine() -> str:
    model = platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{os.cpu_count()} CPUs, {model}, Python {platform.python_version()}"


def _write_json(path: Path, value: Any) -> None:
    path.write_text(json.dumps(value, indent=1))
