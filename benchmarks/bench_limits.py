"""What the limits cost a request (prints JSON).

* ``rate_check_us``: one rate-limit check (GCRA), per call: in this process, and in Redis (one Lua script call
  on ``--redis-url``, the local Redis by default);
* ``http_ms``: median round trip of a cheap API request (``GET /jobs/<unknown id>``, a 404) to a server with
  no rate limit, the in-process one and the Redis one;
* ``quota_admit_ms``: :meth:`Quotas.admit` of a job for a user who owns ``--items`` shapes and job results (the
  counts are queries in a write transaction of the records' database).

    python -m benchmarks.bench_limits [--calls 5000] [--items 100] [--redis-url redis://127.0.0.1:6379/0]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import statistics
import tempfile
import time
import uuid
from pathlib import Path

import httpx

from benchmarks.common import machine, median_ms, start_server
from curvefm.access import Users
from curvefm.records import open_database
from curvefm.records.jobs import JobRow, Jobs
from curvefm.records.shapes import Shapes
from curvefm.service.quotas import quotas
from curvefm.service.ratelimit import MemoryBuckets, RedisBuckets
from curvefm.service.settings import Settings


def percentiles_us(times_s: list[float]) -> dict:
    times = sorted(times_s)
    return {
        "p50": round(1e6 * times[len(times) // 2], 1),
        "p99": round(1e6 * times[int(len(times) * 0.99)], 1),
        "mean": round(1e6 * statistics.fmean(times), 1),
    }


async def rate_checks(buckets, calls: int) -> dict:
    times = []
    for i in range(calls):
        started = time.perf_counter()
        await buckets.wait_s(f"bench-{i % 50}", 1e-6, 1_000_000)
        times.append(time.perf_counter() - started)
    await buckets.close()
    return percentiles_us(times)


def http_ms(folder: Path, redis_url: str, calls: int) -> dict:
    """Servers started side by side, requests interleaved, so the machine's other load falls on all alike."""
    variants = {"none": ("0", ()), "memory": ("1000000", ()), "redis": ("1000000", ("--redis-url", redis_url))}
    servers = {}
    try:
        for name, (rate, redis) in variants.items():
            args = ("--rate-limit", rate, "--rate-burst", "1000000", *redis)
            prefix = {"CURVEFM_QUEUE_PREFIX": f"bench-{uuid.uuid4().hex[:8]}-"}
            servers[name] = start_server(folder / name, args, prefix)
        clients = {name: httpx.Client(base_url=url, headers=headers) for name, (_, url, headers) in servers.items()}
        times = {name: [] for name in servers}
        for _ in range(50 + calls):
            for name, client in clients.items():
                started = time.perf_counter()
                client.get("/jobs/nope")
                times[name].append(time.perf_counter() - started)
        return {name: round(1e3 * statistics.median(values[50:]), 3) for name, values in times.items()}
    finally:
        for server, _, _ in servers.values():
            server.kill()
            server.wait()


def quota_admit_ms(folder: Path, items: int, repeat: int) -> float:
    """One admission of a job (the quotas counted by queries in a write transaction) for a user with ``items``
    shapes and finished jobs with results."""
    database = open_database(folder)
    users, shapes, jobs = Users(database), Shapes(database), Jobs(database)
    users.add("bench")
    user = users.require("bench")
    for i in range(items):
        shapes.add(f"{i:064x}", 1000, user.id)
        jobs.create(JobRow(id=f"job{i}", kind="refine", state="finished", owner="bench", result_bytes=3000))
    settings = Settings(data_dir=folder, quota_sessions=0, quota_jobs=0, quota_bytes=10**12)
    admitting = quotas(settings, database)

    def admit() -> None:
        with admitting.admit(user, "jobs"):
            pass

    return round(median_ms(admit, repeat), 3)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--calls", type=int, default=5000)
    parser.add_argument("--items", type=int, default=100)
    parser.add_argument("--redis-url", default="redis://127.0.0.1:6379/0")
    args = parser.parse_args()
    prefix = f"bench-{uuid.uuid4().hex[:8]}-"
    with tempfile.TemporaryDirectory() as folder:
        report = {
            **machine(),
            "rate_check_us": {
                "memory": asyncio.run(rate_checks(MemoryBuckets(), args.calls)),
                "redis": asyncio.run(rate_checks(RedisBuckets(args.redis_url, prefix), args.calls)),
            },
            "http_ms": http_ms(Path(folder), args.redis_url, args.calls // 10),
            "quota_admit_ms": {"items": args.items, "median": quota_admit_ms(Path(folder) / "quota", args.items, 50)},
        }
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
