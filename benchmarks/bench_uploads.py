"""Peak memory of a real server per upload (``POST /shapes``) against the file's size, one at a time and two at
once (with ``CURVEFM_MAX_CONCURRENT_UPLOADS`` 2 and 1).

The meshes are synthetic grids (a wavy square, two triangles per cell) written as OFF files of about the sizes
asked for, coordinates with 9 decimals, each a new shape (its own offset). ``peak_bytes`` is the growth of the
server process's resident memory during the upload: ``VmHWM`` after resetting it through ``/proc/PID/clear_refs``
(Linux only), so it counts every allocation of reading the body, parsing, validating and storing the mesh;
``peak_per_file_byte`` divides it by the file's size. Each measurement has a new server (embedded, without a
rate limit).

Usage: ``python -m benchmarks.bench_uploads [--sizes-mb 10 20 40]``; prints JSON.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import tempfile
import threading
import time
from pathlib import Path

import httpx
import numpy as np

from benchmarks.common import machine, start_server

OFF_BYTES_PER_VERTEX = 81
"""About what a grid vertex takes in the OFF file: its line and its two faces' lines."""


def write_grid_off(path: Path, megabytes: float, offset: float) -> Path:
    n = max(2, round(math.sqrt(megabytes * 1e6 / OFF_BYTES_PER_VERTEX)))
    u, v = (axis.ravel() for axis in np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n)))
    vertices = np.column_stack([u, v, offset + 0.05 * np.sin(7 * u) * np.cos(5 * v)])
    ids = np.arange(n * n).reshape(n, n)
    a, b, c, d = ids[:-1, :-1].ravel(), ids[:-1, 1:].ravel(), ids[1:, :-1].ravel(), ids[1:, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    with open(path, "w") as f:
        f.write(f"OFF\n{len(vertices)} {len(faces)} 0\n")
        np.savetxt(f, vertices, fmt="%.9f")
        np.savetxt(f, faces, fmt="3 %d %d %d")
    return path


def status_kb(pid: int, key: str) -> int:
    return next(int(line.split()[1]) for line in open(f"/proc/{pid}/status") if line.startswith(key + ":"))


def upload(url: str, headers: dict, path: Path) -> httpx.Response:
    with open(path, "rb") as f:
        return httpx.post(f"{url}/shapes", files={"file": (path.name, f)}, headers=headers, timeout=600)


def measured(pid: int, uploads) -> dict:
    """Run ``uploads`` (a function returning the responses) and measure the server's peak growth."""
    before = status_kb(pid, "VmRSS")
    Path(f"/proc/{pid}/clear_refs").write_text("5")  # the peak := now
    start = time.perf_counter()
    responses = uploads()
    return {
        "seconds": round(time.perf_counter() - start, 2),
        "peak_bytes": 1024 * (status_kb(pid, "VmHWM") - before),
        "statuses": [response.status_code for response in responses],
    }


def at_once(url: str, headers: dict, paths: list[Path]) -> list[httpx.Response]:
    responses: list[httpx.Response] = []
    threads = [threading.Thread(target=lambda p=p: responses.append(upload(url, headers, p))) for p in paths]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return responses


def one_upload(folder: Path, megabytes: float, offset: int) -> dict:
    """A new server each: memory an earlier upload freed to the process's heap would hide part of the peak."""
    server, url, headers = start_server(folder / f"data-{offset}")
    try:
        path = write_grid_off(folder / f"grid{offset}.off", megabytes, offset=offset)
        size = path.stat().st_size
        row = {"file_bytes": size, **measured(server.pid, lambda: [upload(url, headers, path)])}
        return {**row, "peak_per_file_byte": round(row["peak_bytes"] / size, 2)}
    finally:
        server.kill()


def two_at_once(folder: Path, megabytes: float, slots: int) -> dict:
    env = {"CURVEFM_MAX_CONCURRENT_UPLOADS": str(slots)}
    server, url, headers = start_server(folder / f"data-{slots}", env=env)
    try:
        paths = [write_grid_off(folder / f"pair{slots}-{i}.off", megabytes, offset=10 + i) for i in range(2)]
        size = paths[0].stat().st_size
        row = measured(server.pid, lambda: at_once(url, headers, paths))
        return {"max_concurrent_uploads": slots, "file_bytes": size, **row}
    finally:
        server.kill()


def processor() -> str:
    with open("/proc/cpuinfo") as info:
        names = (line.split(":", 1)[1].strip() for line in info if line.startswith("model name"))
        return next(names, platform.processor())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes-mb", type=float, nargs="+", default=[10, 20, 40])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-uploads-") as scratch:
        folder = Path(scratch)
        result = {
            **machine(),
            "processor": processor(),
            "one_at_a_time": [one_upload(folder, megabytes, i) for i, megabytes in enumerate(args.sizes_mb)],
            "two_at_once": [two_at_once(folder, max(args.sizes_mb), slots) for slots in (2, 1)],
        }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
