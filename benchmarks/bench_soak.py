"""Soak: many sessions editing curves at a steady rate against one API process (or several), for minutes.

Starts ``python -m curvefm.service`` (embedded jobs) on a free port, uploads a real pair (FAUST tr_reg_000 ->
tr_reg_001, 6890 vertices, whose vertex ids correspond; ``--pair cat``: TOSCA cat0 -> cat1, 27894 vertices),
computes its bases (k = 120) and opens ``--sessions`` sessions, each with one curve. Then every session edits
``--rate`` times a second for ``--minutes``: it adds a curve (seeded random endpoints, the same ids on both
shapes) while it holds fewer than ``--curves`` curves, and otherwise removes its oldest one. Edits are
scheduled at fixed times (an open loop: a slow answer does not slow the offered load down, the next edit of
that session starts as soon as it can); the load stops at the end, whatever is still scheduled.

Reports the round-trip latency of every edit (p50 / p95 / p99, adds and removes apart), the same from the time
each edit was scheduled (what a user waits for when the server falls behind), the edits sent against those
offered, the errors (any answer but 2xx, or no answer) and the server's resident memory at the start of the
load, in its middle and at its end (and the largest seen, sampled every few seconds), and the CPU time per edit
of the server and of this client. Prints JSON.

The client is aiohttp, not the project's httpx: on a two-core machine the load generator shares the server's
cores, and httpx's asyncio client spent 2 ms of CPU a request when the server kept up and 6 ms when it fell
behind (more connections waiting), which pushed the server further behind; aiohttp spends about 0.65 ms.

``--processes 2``: two API processes on the one data directory (and database), as docker-compose runs them behind
its proxy; ``--spread request`` (default) sends each edit to the next process in turn, as the proxy's round robin
does, ``--spread session`` keeps each session on one process. The CPU per edit is then the processes' together, and
the memory their sum.

``--carry``: each edit asks for the texture carried through its new map in its answer (``?carry=uv&resolution=
display``), as the web UI's edits do now: the map is solved in the edit. ``--texture``: after each edit the session
also fetches that texture (``GET /sessions/{id}/transfer``), as the web UI did before edits carried it: the map is
solved once per revision, on that first read. Without either, the load of scripts editing curves through the API.
The latencies are then those of the edit and its texture together.

Usage: ``python -m benchmarks.bench_soak [--minutes 5] [--sessions 50] [--rate 2] [--pair faust|cat] [--texture]
[--carry] [--processes 1] [--spread request|session] [--data DIR] [--log FILE]``
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import platform
import tempfile
import time
from collections import Counter
from datetime import date
from pathlib import Path

import aiohttp
import numpy as np

from benchmarks.common import scratch_database, shared_data, start_server

PAIRS = {
    "faust": ("faust", "tr_reg_000.off", "tr_reg_001.off"),
    "cat": ("tosca", "cat0.off", "cat1.off"),
}
RSS_EVERY_S = 5.0


def rss_mb(pid: int) -> float:
    """Resident memory of a process (Linux ``/proc``), in MB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return round(int(line.split()[1]) / 1024, 1)
    raise RuntimeError(f"no VmRSS for process {pid}")


async def call(client: aiohttp.ClientSession, method: str, url: str, **kwargs) -> dict:
    """One request whose answer must be a success: its JSON body."""
    async with client.request(method, url, raise_for_status=True, **kwargs) as response:
        return await response.json()


async def prepare(client: aiohttp.ClientSession, pair: str, k: int) -> tuple[list[str], int]:
    """Upload the pair and compute its bases (reused when ``--data`` already has them)."""
    folder, *names = PAIRS[pair]
    ids = []
    for name in names:
        form = aiohttp.FormData()
        form.add_field("file", (shared_data() / folder / name).read_bytes(), filename=name)
        shape = await call(client, "POST", "/shapes", data=form)
        ids.append(shape["id"])
    for shape_id in ids:
        job = await call(client, "POST", f"/shapes/{shape_id}/bases", json={"k": k})
        while (info := await call(client, "GET", f"/jobs/{job['id']}"))["state"] not in ("finished", "failed"):
            await asyncio.sleep(0.5)
        if info["state"] != "finished":
            raise SystemExit(f"basis job failed: {info['error']}")
    return ids, shape["n_file_vertices"]


class Session:
    """One editing session: its id, its curves (oldest first) and the random endpoints it draws."""

    def __init__(self, session_id: str, n_vertices: int, seed: int, home: int = 0):
        self.id, self.n_vertices, self.home = session_id, n_vertices, home  # home: its process (--spread session)
        self.curves: list[str] = []
        self.rng = np.random.default_rng(seed)

    def new_curve(self) -> dict:
        a, b = self.rng.choice(self.n_vertices, 2, replace=False).tolist()
        return {"source": [a, b], "target": [a, b]}


class Load:
    """The edits of all sessions (each through ``clients[i]``, the i-th process's: the session's own with
    ``sticky``, else the next in turn): latencies by kind, errors by status, the servers' memory over time."""

    def __init__(self, servers: list[int], clients: list[aiohttp.ClientSession], args):
        self.servers, self.clients, self.sticky = servers, clients, args.spread == "session"
        self.max_curves, self.texture = args.curves, args.texture
        self.params = {"carry": "uv", "resolution": "display"} if args.carry else {}
        self.sent = 0
        self.latencies: dict[str, list[float]] = {"add": [], "remove": []}
        self.from_schedule: list[float] = []
        self.errors: Counter = Counter()
        self.rss: list[tuple[float, float]] = []

    async def edit(self, session: Session, scheduled: float | None = None) -> None:
        kind = "add" if len(session.curves) < self.max_curves else "remove"
        curves = f"/sessions/{session.id}/curves"
        client = self.clients[(session.home if self.sticky else self.sent) % len(self.clients)]
        self.sent += 1
        started = time.perf_counter()
        try:
            if kind == "add":
                status, body = await self.request(client, "POST", curves, json=session.new_curve(), params=self.params)
            else:
                remove = f"{curves}/{session.curves[0]}"
                status, body = await self.request(client, "DELETE", remove, params=self.params)
            if self.texture and status < 300:
                transfer = f"/sessions/{session.id}/transfer"
                texture, _ = await self.request(client, "GET", transfer, params={"function": "uv"})
                if texture >= 300:
                    self.errors[f"transfer {texture}"] += 1
        except aiohttp.ClientError as exc:
            self.errors[type(exc).__name__] += 1
            return
        answered = time.perf_counter()
        self.latencies[kind].append(1e3 * (answered - started))
        self.from_schedule.append(1e3 * (answered - (scheduled or started)))
        if status >= 300:
            self.errors[str(status)] += 1
        elif kind == "add":
            session.curves.append(json.loads(body)["curve"]["id"])
        else:
            session.curves.pop(0)

    @staticmethod
    async def request(client: aiohttp.ClientSession, method: str, url: str, **kwargs) -> tuple[int, bytes]:
        """(status, body) of one request; the body is read whole, as a client would."""
        async with client.request(method, url, **kwargs) as response:
            return response.status, await response.read()

    async def session_loop(self, session: Session, start: float, end: float, period: float) -> None:
        next_at = start + period * session.rng.random()  # sessions out of step, as people are
        while next_at < end:
            await asyncio.sleep(max(0.0, next_at - time.perf_counter()))
            if time.perf_counter() >= end:
                break
            await self.edit(session, scheduled=next_at)
            next_at += period

    async def sample_memory(self, start: float, end: float) -> None:
        while (now := time.perf_counter()) < end:
            self.rss.append((now - start, self.servers_rss_mb()))
            await asyncio.sleep(min(RSS_EVERY_S, max(0.0, end - now)))
        self.rss.append((time.perf_counter() - start, self.servers_rss_mb()))

    def servers_rss_mb(self) -> float:
        return round(sum(rss_mb(pid) for pid in self.servers), 1)


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of a process so far (Linux ``/proc``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def percentiles(ms: list[float]) -> dict:
    if not ms:
        return {"count": 0}
    p50, p95, p99 = np.percentile(ms, [50, 95, 99])
    return {"count": len(ms), "p50_ms": round(p50, 1), "p95_ms": round(p95, 1), "p99_ms": round(p99, 1)}


async def soak(servers: list[tuple[int, str]], headers: dict[str, str], args) -> dict:
    """The soak against ``servers`` (pid, url) on one data directory: prepared through the first."""
    pids = [pid for pid, _ in servers]
    timeout = aiohttp.ClientTimeout(total=60)
    async with contextlib.AsyncExitStack() as stack:
        clients = [
            await stack.enter_async_context(
                aiohttp.ClientSession(
                    url, headers=headers, timeout=timeout, connector=aiohttp.TCPConnector(limit=args.sessions)
                )
            )
            for _, url in servers
        ]
        started = time.perf_counter()
        ids, n_vertices = await prepare(clients[0], args.pair, args.k)
        prepare_s = time.perf_counter() - started
        sessions = []
        for index in range(args.sessions):
            body = {"source": ids[0], "target": ids[1], "k": args.k, "name": f"soak-{index}"}
            record = await call(clients[0], "POST", "/sessions", json=body)
            sessions.append(Session(record["id"], n_vertices, seed=args.seed + index, home=index % len(clients)))
        load = Load(pids, clients, args)
        for session in sessions:  # the first edit (on each process) builds the live session: not measured
            for _ in range(1 if load.sticky else len(clients)):
                await load.edit(session)
        load.latencies, load.from_schedule = {"add": [], "remove": []}, []
        start = time.perf_counter()
        cpu_start = (sum(map(cpu_s, pids)), time.process_time())
        end = start + 60 * args.minutes
        loops = [load.session_loop(s, start, end, 1 / args.rate) for s in sessions]
        await asyncio.gather(load.sample_memory(start, end), *loops)
        elapsed = time.perf_counter() - start
        cpu = (sum(map(cpu_s, pids)) - cpu_start[0], time.process_time() - cpu_start[1])
    edits = load.latencies["add"] + load.latencies["remove"]
    sent = len(edits) + sum(load.errors.values())
    middle = min(load.rss, key=lambda sample: abs(sample[0] - elapsed / 2))
    return {
        "upload_and_bases_s": round(prepare_s, 1),
        "vertices": n_vertices,
        "edits_offered": round(args.sessions * args.rate * 60 * args.minutes),
        "edits_sent": sent,
        "edits_per_s": round(sent / elapsed, 1),
        "errors": sum(load.errors.values()),
        "cpu_ms_per_edit": {
            "server": round(1e3 * cpu[0] / max(sent, 1), 2),
            "client": round(1e3 * cpu[1] / max(sent, 1), 2),
        },
        "errors_by_kind": dict(load.errors),
        "latency": percentiles(edits),
        "add": percentiles(load.latencies["add"]),
        "remove": percentiles(load.latencies["remove"]),
        "from_schedule": percentiles(load.from_schedule),
        "rss_mb": {
            "start": load.rss[0][1],
            "middle": middle[1],
            "end": load.rss[-1][1],
            "max": max(mb for _, mb in load.rss),
        },
        "rss_series_s_mb": [[round(t), mb] for t, mb in load.rss],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=5.0)
    parser.add_argument("--sessions", type=int, default=50)
    parser.add_argument("--rate", type=float, default=2.0, help="edits per second of each session")
    parser.add_argument("--curves", type=int, default=3, help="curves a session holds before it removes one")
    parser.add_argument("--pair", choices=sorted(PAIRS), default="faust")
    parser.add_argument("--k", type=int, default=120)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--texture", action="store_true", help="fetch the carried texture after each edit")
    parser.add_argument("--carry", action="store_true", help="each edit's answer carries the texture, as the UI's")
    parser.add_argument("--processes", type=int, default=1, help="API processes on the one data directory")
    parser.add_argument(
        "--spread", choices=("request", "session"), default="request", help="next process per edit, or per session"
    )
    parser.add_argument("--data", type=Path, help="data directory (kept; reuses bases); default: a temporary one")
    parser.add_argument("--log", type=Path, help="where the server's output goes (default: nowhere)")
    parser.add_argument("--engine", choices=("sqlite", "postgresql"), default="sqlite", help="the records' database")
    parser.add_argument("--postgres", default="postgresql://postgres@127.0.0.1:5432/test", help="server for a new one")
    args = parser.parse_args()
    with (
        tempfile.TemporaryDirectory(prefix="curvefm-soak-") as scratch,
        scratch_database(args.engine, args.postgres) as database_url,
    ):
        if args.engine == "postgresql":
            os.environ["CURVEFM_DATABASE_URL"] = database_url  # the bench user's token and the server alike
        data = args.data or Path(scratch)
        started = [start_server(data, log=args.log) for _ in range(args.processes)]
        headers = started[-1][2]  # each start rotates the bench user's token: the last one holds
        try:
            result = asyncio.run(soak([(server.pid, url) for server, url, _ in started], headers, args))
        finally:
            for server, _, _ in started:
                server.kill()
                server.wait()
    folder, *names = PAIRS[args.pair]
    report = {
        "benchmark": "soak: curve edits from many sessions against API processes on one data directory",
        "processes": args.processes,
        "spread": args.spread,
        "carry_in_edit_answers": args.carry,
        "shapes": [f"{folder}/{name}" for name in names],
        "k": args.k,
        "sessions": args.sessions,
        "rate_per_session": args.rate,
        "minutes": args.minutes,
        "texture_after_each_edit": args.texture,
        "database": args.engine,
        **result,
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}",
        "date": date.today().isoformat(),
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
