"""Shared helpers for the benchmarks: data location, cached bases, timing."""

import os
import platform
import statistics
import sys
import time
from datetime import date
from pathlib import Path

from curvefm.store import Store

REPO = Path(__file__).resolve().parents[1]


def shared_data() -> Path:
    path = Path(os.environ.get("CURVEFM_SHARED_DATA", REPO.parent / "shared" / "data"))
    if not path.is_dir():
        sys.exit(f"benchmark needs the shared data folder {path} (set CURVEFM_SHARED_DATA)")
    return path


def bench_store() -> Store:
    """Bases cached between benchmark runs (``CURVEFM_BENCH_DATA``, default /tmp/curvefm-bench)."""
    return Store(os.environ.get("CURVEFM_BENCH_DATA", "/tmp/curvefm-bench"))


def machine() -> dict:
    return {"date": date.today().isoformat(), "cpus": os.cpu_count(), "machine": platform.machine(),
            "python": platform.python_version()}


def median_ms(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)
