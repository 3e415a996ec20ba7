"""The paper's Figures 10/11: accuracy against the number of curves, exact vs traced curves, and the
descriptor baselines given the same information (curve endpoints as landmarks, or curves as functions), and the
combined energy (curves, wave kernel signatures and kernel maps along the curves, the default).

Every run is made twice, with the endpoints chosen on the source and with them chosen on the target, and each run's
functional maps are converted to the pointwise maps ``curvefm match`` hands out
(:meth:`~curvefm.evaluation.reproduce.scoring.LoadedPair.score_handed_out`), both of which are scored: a record per
run and direction. :data:`SUMMARIES` names the four summaries; ``summary`` (endpoints on the source, the map source
-> target: the paper's protocol, which the claims and plots use) and ``summary_target_to_source`` (endpoints on the
target, the map target -> source: issue 35's protocol) are the report's main tables."""

from __future__ import annotations

import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from curvefm import registry
from curvefm.errors import CurvefmError
from curvefm.evaluation.protocol import ENDPOINT_SIDES
from curvefm.evaluation.reproduce.datasets import DATASETS, Suite
from curvefm.evaluation.reproduce.scoring import DIRECTIONS, MAX_ROWS, LoadedPair
from curvefm.fmap import DEFAULT_K, Hints
from curvefm.progress import Progress, no_progress
from curvefm.store import Store


@dataclass(frozen=True)
class Variant:
    key: str
    method: str
    label: str
    exact: bool = False
    params: dict[str, Any] = field(default_factory=dict)


VARIANTS = (
    Variant("curves-traced", "curves", "curves (ours), traced"),
    Variant("curves-exact", "curves", "curves (ours), exact", exact=True),
    Variant("combined-traced", "combined", "combined (ours, the default), traced"),
    Variant("obcs12-wks", "obcs12", "OBCS12, descriptors alone (WKS)", params={"landmarks": False}),
    Variant("obcs12", "obcs12", "OBCS12, endpoints as landmarks"),
    Variant("no17", "no17", "NO17, endpoints as landmarks"),
    Variant("no17-curves", "no17", "NO17, curves as functions", params={"inputs": "curves"}),
)


SUMMARIES = {
    "summary": ("source", "source_to_target"),
    "summary_target_to_source": ("target", "target_to_source"),
    "summary_source_ends_target_to_source": ("source", "target_to_source"),
    "summary_target_ends_source_to_target": ("target", "source_to_target"),
}
"""Each summary of ``run_accuracy``'s answer: the side the endpoints are chosen on and the map scored."""


def run_accuracy(data: Path, suite: Suite, store: Store, progress: Progress = no_progress) -> dict[str, Any]:
    """Every variant on every pair, curve count, seed and side the endpoints are chosen on, both maps scored; returns
    records and per-dataset summaries (:data:`SUMMARIES`)."""
    records, skipped = [], []
    tasks = len(suite.pairs) * len(suite.counts) * suite.seeds
    done = 0
    for pair in suite.pairs:
        progress(done / tasks, f"{pair.name}: bases and ground truth")
        loaded = LoadedPair.load(data, pair, DEFAULT_K, store)
        for count in suite.counts:
            if count > loaded.max_curves:
                skipped.append(f"{pair.name}: {count} curves (only {loaded.max_curves} endpoint pairs)")
                done += suite.seeds
                continue
            for seed in range(suite.seeds):
                for side in ENDPOINT_SIDES:
                    records.extend(run_task(loaded, count, seed, side))
                done += 1
                progress(done / tasks, f"{pair.name}: {count} curves, seed {seed}")
    summaries = {key: summarise(records, *scored) for key, scored in SUMMARIES.items()}
    for record in records:  # the summary keeps the cumulative curves; the table keeps the figures per run
        record.pop("curve", None)
    return {"records": records, "skipped": skipped, "sampled_rows": MAX_ROWS} | summaries


def run_task(loaded: LoadedPair, count: int, seed: int, side: str = "source") -> list[dict[str, Any]]:
    """All variants for one random subset of ``count`` curves with endpoints on ``side``: a record per variant and
    direction of the handed-out pointwise maps (both scored away from the curves' ends)."""
    kinds = (False, True) if loaded.truth.dense else (False,)
    curves = {exact: loaded.pools[side].curves(count, seed, exact) for exact in kinds}
    out = []
    for variant in VARIANTS:
        if variant.exact not in curves:
            continue
        hints = Hints.from_curves(curves[variant.exact])
        plugin, params = registry.load("method", variant.method, variant.params)
        record = {
            "dataset": loaded.pair.dataset,
            "pair": loaded.pair.name,
            "variant": variant.key,
            "count": count,
            "seed": seed,
            "endpoints_on": side,
        }
        start = time.perf_counter()
        try:
            maps = plugin.run(loaded.shapes, hints, params, no_progress)
            seconds = time.perf_counter() - start
            errors = loaded.score_handed_out(maps, side, seed, curves[variant.exact])
        except CurvefmError as exc:
            out += [record | {"direction": direction, "failed": str(exc)} for direction in DIRECTIONS.values()]
            continue
        convert_seconds = time.perf_counter() - start - seconds
        for direction, e in errors.items():
            out.append(
                record
                | {"direction": direction, "seconds": seconds, "convert_seconds": convert_seconds, "scored": e.count}
                | {"mean": e.mean, "mean_area": e.mean_area, "auc": e.auc, "curve": e.curve}
            )
    return out


def summarise(
    records: list[dict[str, Any]], endpoints_on: str = "source", direction: str = "source_to_target"
) -> dict[str, Any]:
    """Per dataset, variant and curve count: means over pairs and seeds of the error figures and curves of the maps
    in ``direction`` of the runs with endpoints on ``endpoints_on``."""
    groups = defaultdict(list)
    for r in records:
        if "failed" not in r and (r["endpoints_on"], r["direction"]) == (endpoints_on, direction):
            groups[(r["dataset"], r["variant"], r["count"])].append(r)
    order = {v.key: i for i, v in enumerate(VARIANTS)}
    datasets = list(DATASETS)
    summary: dict[str, Any] = defaultdict(lambda: defaultdict(dict))
    for (dataset, variant, count), rows in sorted(
        groups.items(), key=lambda item: (datasets.index(item[0][0]), order[item[0][1]], item[0][2])
    ):
        summary[dataset][variant][str(count)] = {
            "runs": len(rows),
            "mean": float(np.mean([r["mean"] for r in rows])),
            "mean_area": float(np.mean([r["mean_area"] for r in rows])),
            "auc": float(np.mean([r["auc"] for r in rows])),
            "seconds": float(np.mean([r["seconds"] for r in rows])),
            "curve": [round(float(c), 5) for c in np.mean([r["curve"] for r in rows], axis=0)],
        }
    return {d: {v: dict(c) for v, c in vs.items()} for d, vs in summary.items()}
