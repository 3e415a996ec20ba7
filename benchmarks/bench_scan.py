"""Eigenbases at scan resolution: FAUST tr_reg_000 / tr_reg_011 subdivided 0-3 times (6,890 / 27,554 / 110,210
/ 440,834 vertices; ``trimesh.remesh.subdivide`` keeps the original vertices' ids, so the identity ground truth
holds for them), generated at run time and never written to disk.

For each size, in the same process: the plain ``eigsh(L, k, M=A, sigma=-0.01)``, ``smallest_eigenpairs``
(exact; ``ratio`` = its time / the plain call's) and ``multires_eigenpairs`` (approximate), with eigenvalue
errors relative to the plain call for lambda_1 .. lambda_k-1, and peak memory of the process so far.
With ``--map-level L``, the pair subdivided L times is matched with 10 ground-truth curves (``match``,
defaults) once with the exact basis and once with the multires one; errors (mean geodesic / sqrt(area)) are
measured on the original 6,890 vertices.

With ``--cli-levels 0,4`` the pair at each level is written as binary PLY to a temporary folder with a curves file
(10 curves between 20 farthest points of the original vertices, traced on the subdivided meshes) and run through
``curvefm match`` in a child process under ``/usr/bin/time -v`` (a fresh data folder: both bases are computed;
``--cli-data DIR`` keeps them there between runs); ``--refine zoomout`` adds a refinement. Reported: the child's
wall time and peak resident memory and both maps' errors on the original vertices (mean geodesic error /
sqrt(area), graph geodesics on the subdivided target). Level 4 is 1,763,330 vertices a mesh: run nothing else that
large beside it.

Usage: ``python -m benchmarks.bench_scan [--levels 0,1,2] [--with-440k] [--map-level 2] [--k 120]
[--cli-levels 0,4] [--refine NAME] [--cli-data DIR]``; prints JSON. The 440k level (three subdivisions) needs about
1.5 GB for our solvers, the plain call about 3 GB.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np
import scipy.sparse as sp
import trimesh
from scipy.sparse.linalg import eigsh

from benchmarks.common import machine, shared_data
from curvefm import registry
from curvefm.evaluation import GroundTruth, ground_truth_curves, map_geodesic_errors, score
from curvefm.geometry import build_mesh, cotangent_laplacian, load_mesh, save_mesh
from curvefm.matching import match
from curvefm.runtime import limit_blas_threads
from curvefm.spectral import Basis, multires_eigenpairs, smallest_eigenpairs
from curvefm.store import Store

PAIR = ("tr_reg_000", "tr_reg_011")
DEFAULT_PARAMS = registry.load("basis", "laplace-beltrami", None)[1].model_dump()  # where match looks


def subdivided(name: str, level: int):
    mesh = load_mesh(shared_data() / "faust" / f"{name}.off")
    vertices, faces = mesh.vertices, mesh.faces
    for _ in range(level):
        vertices, faces = trimesh.remesh.subdivide(vertices, faces)
    return build_mesh(vertices, faces, name=f"{name}-subdivided-{level}")


def operators(mesh):
    vertices = mesh.vertices / np.sqrt(mesh.area)
    L, mass = cotangent_laplacian(vertices, mesh.faces)
    return vertices, L, mass / mass.sum()


def timed(fn):
    start = time.perf_counter()
    result = fn()
    return result, time.perf_counter() - start


def peak_gb() -> float:
    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20, 2)


def bench_size(level: int, k: int) -> dict:
    mesh = subdivided(PAIR[0], level)
    vertices, L, mass = operators(mesh)
    (plain, _), plain_s = timed(lambda: eigsh(L, k, M=sp.diags(mass), sigma=-0.01))
    plain = np.sort(plain)
    out = {"vertices": mesh.n_vertices, "plain_s": round(plain_s, 2), "peak_gb_after_plain": peak_gb()}
    (exact, _), exact_s = timed(lambda: smallest_eigenpairs(L, mass, k))
    (approx, _), approx_s = timed(lambda: multires_eigenpairs(L, mass, vertices, mesh.faces, k))
    for name, evals, seconds in (("exact", exact, exact_s), ("multires", approx, approx_s)):
        out[name] = {
            "s": round(seconds, 2),
            "ratio_to_plain": round(seconds / plain_s, 3),
            "max_rel_eigenvalue_error": float(np.max(np.abs(evals[1:] - plain[1:]) / plain[1:])),
        }
    out["peak_gb"] = peak_gb()
    return out


def bench_map(level: int, k: int) -> dict:
    meshes = [subdivided(name, level) for name in PAIR]
    original = meshes[0].internal_ids(np.arange(6890))
    truth = GroundTruth(original, meshes[1].internal_ids(np.arange(6890)), "identity", True)
    curves = ground_truth_curves(meshes[0], meshes[1], truth, 10)
    out = {"vertices": meshes[0].n_vertices}
    for method in ("exact", "multires"):
        with tempfile.TemporaryDirectory() as folder:
            store = Store(folder)
            basis_s = 0.0
            for mesh in meshes:
                vertices, L, mass = operators(mesh)
                solve = smallest_eigenpairs if method == "exact" else multires_eigenpairs
                args = (L, mass, k) if method == "exact" else (L, mass, vertices, mesh.faces, k)
                (evals, evecs), seconds = timed(lambda solve=solve, args=args: solve(*args))
                basis_s += seconds
                store.put_basis(
                    store.put_mesh(mesh), Basis(np.maximum(evals, 0), evecs, mass), "laplace-beltrami", DEFAULT_PARAMS
                )
            result, match_s = timed(lambda store=store: match(meshes[0], meshes[1], curves, store=store))
            errors = score(result, truth)
            out[method] = {
                "bases_s": round(basis_s, 2),
                "match_s": round(match_s, 2),
                "mean_error": errors["source_to_target"]["mean_area"],
                "mean_error_reverse": errors["target_to_source"]["mean_area"],
            }
    out["multires_error_vs_exact"] = round(out["multires"]["mean_error"] / out["exact"]["mean_error"] - 1, 4)
    return out


def original_curves() -> list[dict]:
    """10 curves between 20 farthest points of the original pair, as file-id endpoints (subdivision keeps them)."""
    meshes = [subdivided(name, 0) for name in PAIR]
    ids = np.arange(6890)
    curves = ground_truth_curves(meshes[0], meshes[1], GroundTruth(ids, ids, "identity", True), 10)
    return [{"source": [int(a[0]), int(a[-1])], "target": [int(b[0]), int(b[-1])]} for a, b in curves]


def bench_cli(level: int, k: int, refine: str, folder: str, data: str | None) -> dict:
    paths = [os.path.join(folder, f"{name}-{level}.ply") for name in PAIR]
    for name, path in zip(PAIR, paths, strict=True):
        mesh = subdivided(name, level)
        save_mesh(mesh, path)
        vertices = mesh.n_vertices
        del mesh  # one mesh in memory at a time
    curves = os.path.join(folder, "curves.json")
    with open(curves, "w") as out:
        json.dump({"curves": original_curves()}, out)
    out_dir = os.path.join(folder, f"out-{level}")
    command = [
        sys.executable,
        "-m",
        "curvefm.cli",
        "match",
        *paths,
        "--curves",
        curves,
        "--out",
        out_dir,
        "--k",
        str(k),
    ]
    command += ["--data", data or os.path.join(folder, f"data-{level}"), "--refine", refine]
    log = os.path.join(folder, "match.log")
    print(f"curvefm match at level {level}: progress in {log}", file=sys.stderr, flush=True)
    start = time.perf_counter()
    with open(log, "w") as stderr:
        run = subprocess.run(["/usr/bin/time", "-v", *command], stdout=subprocess.DEVNULL, stderr=stderr, check=False)
    seconds = time.perf_counter() - start
    output = open(log).read()
    if run.returncode != 0:
        raise RuntimeError(f"curvefm match failed at level {level}: {output[-3000:]}")
    peak_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", output)[1])
    out = {"vertices": vertices, "refine": refine}
    out |= {"match_s": round(seconds, 1), "peak_gb": round(peak_kb / 2**20, 2), "bases_kept": data is not None}
    out["errors"] = {direction: cli_error(out_dir, level, direction) for direction in ("source", "target")}
    out["quality"] = json.loads(open(os.path.join(out_dir, "quality.json")).read())["kept"]
    return out


def cli_error(out_dir: str, level: int, side: str) -> float:
    """Mean geodesic error / sqrt(area) of the map from ``side`` on the original vertices, measured on the other."""
    name, mapped = (PAIR[1], "source_to_target") if side == "source" else (PAIR[0], "target_to_source")
    p2p = np.loadtxt(os.path.join(out_dir, f"map_{mapped}.txt"), dtype=np.int64)
    image = subdivided(name, level)
    original = np.arange(6890)
    errors = map_geodesic_errors(p2p, (original, original), image, diagonals=True)
    return round(float(errors.mean() / np.sqrt(image.area)), 5)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", default="0,1,2", help="subdivision levels to time (default %(default)s)")
    parser.add_argument("--with-440k", action="store_true", help="also time three subdivisions (440,834 vertices)")
    parser.add_argument("--map-level", type=int, default=None, help="match the pair at this level (2: 110k)")
    parser.add_argument("--k", type=int, default=120)
    parser.add_argument("--cli-levels", default="", help="run `curvefm match` on the pair at these levels (0,4)")
    parser.add_argument("--refine", default="nearest-neighbor", help="the converter `curvefm match` uses")
    parser.add_argument("--cli-data", help="the data folder `curvefm match` keeps its bases in (default: a fresh one)")
    args = parser.parse_args()
    levels = [int(level) for level in args.levels.split(",") if level] + ([3] if args.with_440k else [])
    load_before = round(os.getloadavg()[0], 2)  # other processes on the machine skew every timing
    report: dict = {"machine": machine(), "k": args.k, "sizes": {}}
    for level in levels:
        report["sizes"][str(level)] = bench_size(level, args.k)
        print(json.dumps(report["sizes"][str(level)]), file=sys.stderr, flush=True)
    if args.map_level is not None:
        report["map"] = bench_map(args.map_level, args.k)
    for level in [int(level) for level in args.cli_levels.split(",") if level]:
        with tempfile.TemporaryDirectory() as folder:
            report.setdefault("cli", {})[str(level)] = bench_cli(level, args.k, args.refine, folder, args.cli_data)
        print(json.dumps(report["cli"][str(level)]), file=sys.stderr, flush=True)
    report["machine"]["load_avg_1min_before_after"] = [load_before, round(os.getloadavg()[0], 2)]
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    limit_blas_threads()
    main()
