"""The whole ``curvefm basis --k 120`` command against the plain pipeline, each a fresh Python process.

For each size: (a) ``python -m curvefm.cli basis MESH --k K --data FRESH`` (a new, empty data directory each run,
so the basis is computed and written), and (b) the plain pipeline in its own process, its imports included:
read the mesh (curvefm's reader), the cotangent Laplacian and lumped mass of the unit-area mesh, scipy's
``eigsh(L, k, M=A, sigma=-0.01)``. curvefm's bytecode is written first, as installing it does. Both run with the
BLAS threads the command sets itself (one, unless ``OPENBLAS_NUM_THREADS`` etc. are set), alternating (a) (b) (a)
(b) ..., ``--repeats`` times; wall seconds from the start of the process to its exit, its CPU seconds and peak
resident memory (``wait4``), and the ratio (a) / (b) of each pair with its spread (wall seconds; on a loaded
machine the CPU seconds say more).

``breakdown``: one more run of the command under cProfile: where its time goes (imports = the whole run less
``main``; reading, the Laplacian, the eigensolver and its parts, writing the store's files). Profiling slows
Python-heavy parts more than the native ones, so its total exceeds the unprofiled runs.

Sizes: ``28k`` TOSCA cat0 (27,894 vertices), ``110k`` / ``440k`` FAUST tr_reg_000 subdivided twice / three
times (``trimesh.remesh.subdivide``), written as binary PLY to a temporary folder at run time.

Usage: ``python -m benchmarks.bench_basis_command [--sizes 28k,110k,440k] [--repeats 3] [--k 120] [--params JSON]
[--no-breakdown]``; prints JSON. Data: $CURVEFM_SHARED_DATA or ../shared/data next to the repository. The 440k
plain call peaks at about 3 GB.
"""

from __future__ import annotations

import argparse
import json
import os
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FAUST = "tr_reg_000"
SIZES = {"28k": ("tosca", 0), "110k": ("faust", 2), "440k": ("faust", 3)}
# what the breakdown reports: label -> (file suffix, function name) of cProfile's entries, cumulative seconds
PARTS = {
    "main": ("curvefm/cli.py", "main"),
    "read": ("curvefm/geometry/mesh_io.py", "load_mesh"),
    "laplacian": ("curvefm/geometry/laplacian.py", "cotangent_laplacian"),
    "eigensolver_exact": ("curvefm/spectral/eigensolver.py", "smallest_eigenpairs"),
    "eigensolver_multires": ("curvefm/spectral/multires.py", "multires_eigenpairs"),
    "multires_coarse_space": ("curvefm/spectral/multires.py", "prolongation"),
    "factorisation": ("curvefm/spectral/eigensolver.py", "shifted_factor"),
    "write_mesh": ("curvefm/store.py", "put_mesh"),
    "write_basis": ("curvefm/store.py", "put_basis"),
}


def plain_pipeline(path: str, k: int) -> None:
    """(b): what a user without curvefm's solver runs. Imports inside, so the process pays for them."""
    import numpy as np
    import scipy.sparse as sp
    from scipy.sparse.linalg import eigsh

    from curvefm.geometry import cotangent_laplacian, load_mesh

    mesh = load_mesh(path)
    L, mass = cotangent_laplacian(mesh.vertices / np.sqrt(mesh.area), mesh.faces)
    evals, _ = eigsh(L, k, M=sp.diags(mass / mass.sum()), sigma=-0.01)
    print(json.dumps({"vertices": mesh.n_vertices, "lambda_1": float(np.sort(evals)[1])}))


def compile_curvefm(env: dict[str, str]) -> None:
    """Write the bytecode of the curvefm the children import, as installing a package does: under
    ``PYTHONDONTWRITEBYTECODE`` every run would compile each curvefm module it imports again (about 0.35 s of the
    command's start on a loaded machine, less for the plain pipeline, which imports fewer of them)."""
    code = "import compileall, curvefm; compileall.compile_dir(curvefm.__path__[0], quiet=1)"
    subprocess.run([sys.executable, "-c", code], check=True, env=env)


def write_mesh(size: str, folder: Path) -> Path:
    from benchmarks.common import shared_data

    source, level = SIZES[size]
    if source == "tosca":
        return shared_data() / "tosca" / "cat0.off"
    import trimesh

    from curvefm.geometry import build_mesh, load_mesh, save_mesh

    mesh = load_mesh(shared_data() / "faust" / f"{FAUST}.off")
    vertices, faces = mesh.vertices, mesh.faces
    for _ in range(level):
        vertices, faces = trimesh.remesh.subdivide(vertices, faces)
    path = folder / f"{FAUST}-subdivided-{level}.ply"
    save_mesh(build_mesh(vertices, faces, name=path.stem), path)
    return path


def run_process(command: list[str], env: dict[str, str]) -> dict:
    """Wall seconds, CPU seconds and peak resident memory of one child process (its stdout/stderr discarded)."""
    with tempfile.TemporaryFile() as stderr:  # a file, not a pipe: a full pipe would stop the child
        start = time.perf_counter()
        process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=stderr, env=env)
        _, status, usage = os.wait4(process.pid, 0)
        seconds = time.perf_counter() - start
        if os.waitstatus_to_exitcode(status) != 0:
            stderr.seek(0)
            sys.exit(f"{' '.join(command)} failed:\n{stderr.read().decode(errors='replace')[-3000:]}")
    cpu = usage.ru_utime + usage.ru_stime  # with the children it waited for (the command's slice worker)
    return {"s": round(seconds, 2), "cpu_s": round(cpu, 2), "peak_gb": round(usage.ru_maxrss / 2**20, 2)}


def command_line(path: Path, k: int, data: str, params: str) -> list[str]:
    return [sys.executable, "-m", "curvefm.cli", "basis", str(path), "--k", str(k), "--data", data, "--params", params]


def bench_size(path: Path, k: int, repeats: int, params: str, env: dict[str, str], work: Path) -> dict:
    runs = []
    for run in range(repeats):
        ours = run_process(command_line(path, k, str(work / f"data-{path.stem}-{run}"), params), env)
        plain_command = [sys.executable, "-m", "benchmarks.bench_basis_command", "--plain", str(path), "--k", str(k)]
        plain = run_process(plain_command, env)
        ratio, cpu_ratio = round(ours["s"] / plain["s"], 3), round(ours["cpu_s"] / plain["cpu_s"], 3)
        runs.append({"command": ours, "plain": plain, "ratio": ratio, "cpu_ratio": cpu_ratio})
    return {"runs": runs} | {f"{key}_min_median_max": _spread([r[key] for r in runs]) for key in ("ratio", "cpu_ratio")}


def _spread(values: list[float]) -> list[float]:
    values = sorted(values)
    return [values[0], values[len(values) // 2], values[-1]]


def breakdown(path: Path, k: int, params: str, env: dict[str, str], work: Path) -> dict:
    profile = work / f"{path.stem}.prof"
    data = str(work / f"data-{path.stem}-profiled")
    command = [sys.executable, "-m", "cProfile", "-o", str(profile), *command_line(path, k, data, params)[1:]]
    start = time.perf_counter()
    subprocess.run(command, check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    total = time.perf_counter() - start
    stats = pstats.Stats(str(profile)).stats  # type: ignore[attr-defined]
    found = {}
    for label, (suffix, name) in PARTS.items():
        seconds = [v[3] for (file, _, func), v in stats.items() if file.endswith(suffix) and func == name]
        if seconds:
            found[label] = round(max(seconds), 2)
    found["profiled_total"] = round(total, 2)
    found["imports_and_start"] = round(total - found.pop("main", 0.0), 2)
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="28k,110k")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--k", type=int, default=120)
    parser.add_argument("--params", default="{}", help="the command's --params (JSON), e.g. a method")
    parser.add_argument("--no-breakdown", action="store_true")
    parser.add_argument("--plain", help=argparse.SUPPRESS)  # the child process of (b)
    args = parser.parse_args()
    if args.plain:
        plain_pipeline(args.plain, args.k)
        return
    from benchmarks.common import machine

    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(Path(__file__).resolve().parents[1] / "src"))
    for variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):  # as the command sets them
        env.setdefault(variable, "1")
    compile_curvefm(env)
    report: dict = {"machine": machine(), "params": args.params, "load_avg_1min_before": round(os.getloadavg()[0], 2)}
    report["sizes"] = {}
    with tempfile.TemporaryDirectory(prefix="bench-basis-") as tmp:
        work = Path(tmp)
        for size in args.sizes.split(","):
            path = write_mesh(size, work)
            result = bench_size(path, args.k, args.repeats, args.params, env, work)
            if not args.no_breakdown:
                result["breakdown_s"] = breakdown(path, args.k, args.params, env, work)
            report["sizes"][size] = result
    report["load_avg_1min_after"] = round(os.getloadavg()[0], 2)
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
