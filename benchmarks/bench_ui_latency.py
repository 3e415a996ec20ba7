"""Click-to-new-texture in the browser, and responsiveness of the page on a 50k-vertex pair.

Starts ``python -m curvefm.service`` (embedded jobs) on a free port, uploads a pair from ../shared/data, computes
its bases (k = 120) through the job queue (kept in ``--data`` between runs), creates a session and opens the
web UI in headless Chromium (WebGL through SwiftShader, i.e. drawn on the CPU). Then:

* ``latency`` (TOSCA cat0 -> cat1, 27894 vertices): ``--curves`` curves entered by real mouse clicks on
  rendered vertices (start and end on the source, then on the target, each click once the previous one's
  marker is on screen, as a person would). For each, the page measures the time from the click that completes
  the curve to the moment the frame with the new texture has been drawn (a WebGL fence after the draw has
  signalled): the POST of the curve (trace both paths, update both maps, store the session), the GET of the
  carried texture coordinates, the attribute update and the draw. Reports p50 / p95 and the parts.
* ``responsiveness`` (TOSCA david0 -> david1, 52565 vertices; with ``--scan-level``, the scan pair): the longest
  main-thread task
  (``PerformanceObserver('longtask')``) and the longest gap between animation frames while the session loads
  and while ``--large-curves`` curves are added; the page counts as frozen from a gap of 1 s.

``--pause S`` waits S seconds after each curve, as a person would between curves: from about 1.5 s the
landmark prior (computed once a session has had no new curve for a second) runs beside the next curve's clicks.

``--scan-level L`` measures ``latency`` on FAUST tr_reg_000 -> tr_reg_011 subdivided L times instead
(``trimesh.remesh.subdivide``, generated at run time and uploaded as PLY, never kept: 110,210 vertices
for L = 2, where issue 14's budget is p95 <= 150 ms). Shapes above the server's ``CURVEFM_DISPLAY_VERTICES``
(default 50,000) are drawn as display copies; set it to 0 in the environment to draw them whole.

``--transfer-levels L ...`` times, without the browser, what the page reads of FAUST subdivided L times (2:
110,210 vertices, 3: 440,834): ``GET /sessions/{id}/transfer?function=uv`` with one row per vertex
(``resolution=full``) and per display vertex (``resolution=display``), interleaved, after a read that solved the
map; and the gzipped bytes of ``GET /shapes/{id}/mesh`` for the display copy and the whole mesh, with the time of
the first request for the copy (made by the basis job since issue 37, so read; before, that request made it); and
the round trips of ten edits as the page sends them (``?carry=uv&resolution=display``: trace, solve, store and the
carried texture coordinates at display rows; the first five are the five measured before 2026-11-28 11:30).

``--worker-memory SIZE`` runs the jobs on one ``curvefm worker`` with that memory budget (``--memory``) on a private
``redis-server`` instead of the server's in-process executor, and reports the worker's peak resident memory (its
work horses' included, from ``/usr/bin/time``). With ``--scan-level 4`` (1,763,330 vertices a shape) the bases take
minutes each: keep ``--data`` between runs, the second run finds them.

Endpoints are pairs of vertices visible on both shapes with the same id (TOSCA poses of one class, and FAUST
registrations, correspond by id), sampled on a grid over the source canvas, at least 120 pixels apart. Prints JSON.

Usage: ``python -m benchmarks.bench_ui_latency [--data DIR] [--curves N] [--pause S] [--large-curves M] [--no-large]
[--scan-level L] [--transfer-levels L ...] [--transfer-reads N] [--worker-memory SIZE]``
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np

from benchmarks.bench_queues import start_redis
from benchmarks.bench_scan import subdivided
from benchmarks.common import REPO, machine, shared_data, start_server
from curvefm.geometry import save_mesh

sys.path.insert(0, str(REPO / "tests"))
from support.ui import (  # noqa: E402  (shared with the browser tests: tests/support/ui.py)
    CHROMIUM,
    VIEWPORT,
    click_curve,
    endpoint_pairs,
    launch,
    open_session,
    pickable_vertices,
)

K = 120
LATENCY_PAIR = ("cat0.off", "cat1.off")
LARGE_PAIR = ("david0.off", "david1.off")
SCAN_PAIR = ("tr_reg_000", "tr_reg_011")
FROZEN_GAP_MS = 1000
EDITS = [[412, 5910], [3500, 6500], [1200, 4400], [2000, 6100], [800, 3100]] + [
    [100, 5200],
    [2600, 4900],
    [5500, 300],
    [1700, 6700],
    [4100, 900],
]
"""Curves of ``--transfer-levels``' edits, between original FAUST vertices (their ids hold at every level)."""

# Installed before the page's own scripts: records long tasks and the gaps between animation frames.
MONITOR_JS = """
window.curvefmMonitor = { longTasks: [], maxGap: 0, last: null, reset() { this.longTasks = []; this.maxGap = 0; } };
new PerformanceObserver((list) => {
  for (const entry of list.getEntries()) window.curvefmMonitor.longTasks.push(entry.duration);
}).observe({ type: "longtask", buffered: true });
const tick = (now) => {
  const m = window.curvefmMonitor;
  if (m.last !== null) m.maxGap = Math.max(m.maxGap, now - m.last);
  m.last = now;
  requestAnimationFrame(tick);
};
requestAnimationFrame(tick);
"""


def tosca_files(names: tuple[str, str]) -> list[tuple[str, bytes]]:
    return [(name, (shared_data() / "tosca" / name).read_bytes()) for name in names]


def subdivided_faust(level: int) -> list[tuple[str, bytes]]:
    """FAUST tr_reg_000 and tr_reg_011 subdivided ``level`` times, as PLY files in memory, byte for byte those of
    ``bench_scan --cli-levels`` (so bases that ``curvefm match`` computed there serve here too)."""
    files = []
    with tempfile.TemporaryDirectory() as folder:
        for name in SCAN_PAIR:
            path = Path(folder) / f"{name}_x{level}.ply"
            save_mesh(subdivided(name, level), path)
            files.append((path.name, path.read_bytes()))
    return files


def prepare_session(client: httpx.Client, files: list[tuple[str, bytes]]) -> tuple[str, int]:
    """Upload the pair, compute its bases, create a session: (session id, source vertex count)."""
    ids, n_vertices = [], 0
    for name, content in files:
        shape = client.post("/shapes", files={"file": (name, content)}).raise_for_status().json()
        ids.append(shape["id"])
        n_vertices = n_vertices or shape["n_vertices"]
    for shape_id in ids:
        job = client.post(f"/shapes/{shape_id}/bases", json={"k": K}).raise_for_status().json()
        while (info := client.get(f"/jobs/{job['id']}").json())["state"] not in ("finished", "failed", "canceled"):
            time.sleep(0.5)
        if info["state"] != "finished":
            raise SystemExit(f"basis job {info['state']}: {info['error']}")
    session = client.post("/sessions", json={"source": ids[0], "target": ids[1], "k": K, "name": "bench-ui"})
    return session.raise_for_status().json()["id"], n_vertices


def percentile(values: list[float], q: float) -> float:
    return round(float(np.percentile(values, q)), 1)


def cpu_seconds(pid: int) -> float:
    """User and system CPU time of process ``pid`` so far (Linux)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure_latency(
    browser,
    url: str,
    token: str,
    session_id: str,
    n_vertices: int,
    curves: int,
    pair: str,
    pause_s: float = 0.0,
    server_pid: int | None = None,
) -> dict:
    page = browser.new_page(viewport=VIEWPORT)
    open_session(page, url, session_id, token, timeout_ms=120_000)
    pairs = endpoint_pairs(pickable_vertices(page), curves)
    samples = []
    server_cpu = cpu_seconds(server_pid) if server_pid else 0.0
    for ends in pairs:
        samples.append(click_curve(page, list(ends)))
        time.sleep(pause_s)
    server_cpu = cpu_seconds(server_pid) - server_cpu if server_pid else None
    page.close()
    total = [s["totalMs"] for s in samples]
    parts = (("edit_request", "editMs"), ("transfer", "transferMs"), ("draw", "drawMs"))
    return {
        "pair": pair,
        "vertices": n_vertices,
        "k": K,
        "curves": curves,
        "pause_s": pause_s,
        "click_to_texture_ms": {"p50": percentile(total, 50), "p95": percentile(total, 95), "max": max(total)},
        "parts_median_ms": {part: percentile([s[key] for s in samples], 50) for part, key in parts},
        "parts_p95_ms": {part: percentile([s[key] for s in samples], 95) for part, key in parts},
        "server_solve_median_ms": percentile([s["solveMs"] for s in samples], 50),
        "requests_per_click": max(s.get("requests", 2) for s in samples),
        # everything the server did while the curves were entered (edits, reads after them, priors), per curve
        "server_cpu_ms_per_curve": None if server_cpu is None else round(1000 * server_cpu / curves, 1),
        "samples_ms": total,
        "samples_parts_ms": [[s[key] for _, key in parts] for s in samples],
    }


def measure_responsiveness(
    browser, url: str, token: str, session_id: str, n_vertices: int, curves: int, pair: str
) -> dict:
    page = browser.new_page(viewport=VIEWPORT)
    page.add_init_script(MONITOR_JS)
    started = time.perf_counter()
    open_session(page, url, session_id, token, timeout_ms=180_000)
    load_s = time.perf_counter() - started
    loading = page.evaluate("({ longest: Math.max(0, ...curvefmMonitor.longTasks), maxGap: curvefmMonitor.maxGap })")
    pairs = endpoint_pairs(pickable_vertices(page), curves)  # the test hook's raycasts are not the page's work
    page.evaluate("curvefmMonitor.reset()")
    samples = [click_curve(page, list(pair)) for pair in pairs]
    editing = page.evaluate("({ longest: Math.max(0, ...curvefmMonitor.longTasks), maxGap: curvefmMonitor.maxGap })")
    page.close()
    return {
        "pair": pair,
        "vertices": n_vertices,
        "load_to_first_texture_s": round(load_s, 2),
        "loading": {"longest_task_ms": round(loading["longest"]), "max_frame_gap_ms": round(loading["maxGap"])},
        "editing": {
            "curves": curves,
            "longest_task_ms": round(editing["longest"]),
            "max_frame_gap_ms": round(editing["maxGap"]),
            "click_to_texture_ms": [s["totalMs"] for s in samples],
        },
        "frozen": max(loading["maxGap"], editing["maxGap"]) >= FROZEN_GAP_MS,
    }


def ms_since(started: float) -> float:
    return (time.perf_counter() - started) * 1000


def mesh_payloads(client: httpx.Client, shape_id: str) -> dict:
    """Bytes on the wire (gzipped) of the target's mesh payload, display copy and whole; the first request for the
    copy reads it (the basis job made it)."""
    found = {}
    for resolution in ("display", "full"):
        started = time.perf_counter()
        response = client.get(f"/shapes/{shape_id}/mesh", params={"resolution": resolution}).raise_for_status()
        found[resolution] = {"wire_bytes": response.num_bytes_downloaded, "first_request_ms": round(ms_since(started))}
    return found


def measure_transfer(client: httpx.Client, session_id: str, reads: int) -> dict:
    """Round trips of the uv transfer with full and display rows, interleaved, after one read of each."""
    url, times, rows = f"/sessions/{session_id}/transfer", {"full": [], "display": []}, {}
    for read in range(reads + 1):
        for resolution in times:
            started = time.perf_counter()
            response = client.get(url, params={"function": "uv", "resolution": resolution}).raise_for_status()
            if read:
                times[resolution].append(ms_since(started))
            rows[resolution] = int(response.headers["X-Shape"].split(",")[0])
    return {
        resolution: {"rows": rows[resolution], "p50_ms": percentile(ms, 50), "p95_ms": percentile(ms, 95)}
        for resolution, ms in times.items()
    }


def measure_scan_reads(client: httpx.Client, level: int, reads: int) -> dict:
    """What the page reads of FAUST subdivided ``level`` times: the transfer and the mesh payloads."""
    session_id, n = prepare_session(client, subdivided_faust(level))
    record = client.get(f"/sessions/{session_id}").raise_for_status().json()
    ends = [0, n // 2]  # any two vertices: the map's content does not change the cost of reading it
    client.post(f"/sessions/{session_id}/curves", json={"source": ends, "target": ends}).raise_for_status()
    return {
        "level": level,
        "vertices": n,
        "mesh_payload": mesh_payloads(client, record["target"]),
        "transfer_uv": measure_transfer(client, session_id, reads),
        "edit_with_carry": measure_edits(client, session_id, EDITS),
    }


def measure_edits(client: httpx.Client, session_id: str, curves: list[list[int]]) -> dict:
    """Round trips of the page's edit (``?carry=uv&resolution=display``): a curve between two original FAUST
    vertices (the same ids on both shapes) traced on both, both maps updated, the texture coordinates carried."""
    url, times = f"/sessions/{session_id}/curves", []
    for ends in curves:
        started = time.perf_counter()
        response = client.post(
            url, params={"carry": "uv", "resolution": "display"}, json={"source": ends, "target": ends}
        )
        times.append(ms_since(started))
        response.raise_for_status()
    return {"curves": len(curves), "p50_ms": percentile(times, 50), "ms": [round(ms, 1) for ms in times]}


def pair_files(scan_level: int, tosca_pair: tuple[str, str]) -> tuple[list[tuple[str, bytes]], str]:
    """The files of FAUST subdivided ``scan_level`` times, or of a TOSCA pair, and the pair's name."""
    if scan_level:
        return subdivided_faust(scan_level), f"FAUST {'/'.join(SCAN_PAIR)} x{scan_level}"
    return tosca_files(tosca_pair), "/".join(tosca_pair)


def measure_in_browser(
    browser, client: httpx.Client, url: str, token: str, args: argparse.Namespace, server_pid: int
) -> dict:
    """The latency (unless ``--curves 0``) and the responsiveness (unless ``--no-large``) sections."""
    result = {}
    if args.curves:
        files, pair = pair_files(args.scan_level, LATENCY_PAIR)
        session_id, n = prepare_session(client, files)
        result["latency"] = measure_latency(
            browser, url, token, session_id, n, args.curves, pair, args.pause, server_pid
        )
    if not args.no_large:
        files, pair = pair_files(args.scan_level, LARGE_PAIR)
        session_id, n = prepare_session(client, files)
        result["responsiveness"] = measure_responsiveness(browser, url, token, session_id, n, args.large_curves, pair)
    return result


def start_worker(redis_url: str, memory: str, log: Path) -> subprocess.Popen:
    """One ``curvefm worker`` on every queue with the budget ``memory``, under ``/usr/bin/time -v`` (into ``log``)."""
    command = [sys.executable, "-m", "curvefm.workers", "--redis-url", redis_url, "--memory", memory]
    return subprocess.Popen(["/usr/bin/time", "-v", *command], stdout=subprocess.DEVNULL, stderr=open(log, "w"))  # noqa: SIM115


def worker_peak_gb(worker: subprocess.Popen, log: Path) -> float | None:
    """The worker's peak resident memory (its largest work horse's, or its own) once it has stopped."""
    children = Path(f"/proc/{worker.pid}/task/{worker.pid}/children").read_text().split()
    for child in children:  # the worker itself: /usr/bin/time waits for it and then writes its report
        os.kill(int(child), signal.SIGTERM)
    worker.wait(timeout=60)
    found = re.search(r"Maximum resident set size \(kbytes\): (\d+)", log.read_text())
    return round(int(found[1]) / 2**20, 2) if found else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", default=os.environ.get("CURVEFM_BENCH_DATA", "/tmp/curvefm-bench"))
    parser.add_argument("--curves", type=int, default=20, help="0: no latency run (with --no-large: no browser)")
    parser.add_argument(
        "--pause",
        type=float,
        default=0.0,
        help="seconds between curves: from about 1.5, the landmark prior runs beside the next clicks",
    )
    parser.add_argument("--large-curves", type=int, default=3)
    parser.add_argument("--no-large", action="store_true", help="skip the 50k-vertex responsiveness check")
    parser.add_argument("--scan-level", type=int, default=0, help="latency on FAUST subdivided this many times")
    parser.add_argument("--transfer-levels", type=int, nargs="*", default=[], help="time the reads at these levels")
    parser.add_argument("--transfer-reads", type=int, default=40)
    parser.add_argument("--worker-memory", help="run the jobs on a curvefm worker with this budget (e.g. 12G)")
    args = parser.parse_args()
    if not CHROMIUM.is_file():
        sys.exit(f"benchmark needs Chromium at {CHROMIUM} (set CURVEFM_CHROMIUM)")
    from playwright.sync_api import sync_playwright

    folder = Path(tempfile.mkdtemp(prefix="curvefm-bench-ui-"))
    helpers, server_args = [], ("--rate-limit", "0")
    if args.worker_memory:
        redis, redis_url = start_redis(folder)
        helpers = [redis, start_worker(redis_url, args.worker_memory, folder / "worker.log")]
        server_args += ("--redis-url", redis_url)
    server, url, headers = start_server(Path(args.data), server_args)
    token = headers["Authorization"].split()[-1]
    try:
        client = httpx.Client(base_url=url, timeout=600, headers=headers)
        result = {"machine": {**machine(), "load_average_1min": os.getloadavg()[0]}, "renderer": "SwiftShader"}
        if args.curves or not args.no_large:
            with sync_playwright() as playwright:
                browser = launch(playwright)
                result.update(measure_in_browser(browser, client, url, token, args, server.pid))
                browser.close()
        reads = [measure_scan_reads(client, level, args.transfer_reads) for level in args.transfer_levels]
        if reads:
            result["scan_reads"] = reads
        result["machine"]["load_average_1min_end"] = os.getloadavg()[0]
        if args.worker_memory:
            result["worker"] = {
                "memory": args.worker_memory,
                "peak_gb": worker_peak_gb(helpers[1], folder / "worker.log"),
            }
        print(json.dumps(result, indent=1))
    finally:
        server.terminate()
        server.wait(timeout=30)
        for helper in reversed(helpers):
            helper.kill()
            helper.wait()


if __name__ == "__main__":
    main()
