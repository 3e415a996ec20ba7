"""Eigenbasis k = 120: ``curvefm.spectral.smallest_eigenpairs`` against the plain ``eigsh(L, k, M=A, sigma=-0.01)``.

Budget (docs/performance.md): on a 30k-vertex mesh, <= 0.5x the plain call's time with the same eigenvalues (1e-6
relative). Meshes: FAUST tr_reg_000 (6890 vertices) and TOSCA cat0 (27894), built as the basis plugin builds
them (unit area, cotangent Laplacian, lumped mass). Configurations run interleaved, ``--repeats`` times each;
times are medians of wall seconds. ``ours`` is the default (two slice processes from 15k vertices on);
``ours_serial`` and ``ours_sliced`` force ``workers=1`` and ``workers=2``.

Eigenvalue differences are relative for lambda_1 .. lambda_k-1 and absolute for lambda_0 (which is 0).

Usage: ``python -m benchmarks.bench_eigenbasis [--repeats N] [--k K]``; prints JSON. Data: $CURVEFM_SHARED_DATA
or ../shared/data next to the repository.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh

from curvefm.geometry import cotangent_laplacian, load_mesh
from curvefm.runtime import limit_blas_threads
from curvefm.spectral import smallest_eigenpairs

DATA = Path(os.environ.get("CURVEFM_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
MESHES = {"faust_tr_reg_000": "faust/tr_reg_000.off", "tosca_cat0": "tosca/cat0.off"}


def plain(L: sp.csr_matrix, mass: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    evals, evecs = eigsh(L, k, M=sp.diags(mass), sigma=-0.01)
    order = np.argsort(evals)
    return evals[order], evecs[:, order]


def bench_mesh(path: Path, k: int, repeats: int) -> dict:
    mesh = load_mesh(path)
    L, mass = cotangent_laplacian(mesh.vertices / np.sqrt(mesh.area), mesh.faces)
    mass = mass / mass.sum()
    configs = {
        "plain": plain,
        "ours": smallest_eigenpairs,
        "ours_serial": lambda L, mass, k: smallest_eigenpairs(L, mass, k, workers=1),
        "ours_sliced": lambda L, mass, k: smallest_eigenpairs(L, mass, k, workers=2),
    }
    times: dict[str, list[float]] = {name: [] for name in configs}
    results = {}
    for _ in range(repeats):
        for name, run in configs.items():
            t0 = time.perf_counter()
            results[name] = run(L, mass, k)
            times[name].append(time.perf_counter() - t0)
    ref = results["plain"][0]
    out: dict = {"vertices": mesh.n_vertices, "k": k, "plain_s": round(float(np.median(times["plain"])), 3)}
    for name in configs:
        if name == "plain":
            continue
        evals, evecs = results[name]
        median = float(np.median(times[name]))
        out[name] = {
            "median_s": round(median, 3),
            "ratio": round(median / float(np.median(times["plain"])), 3),
            "max_rel_eigenvalue_diff": float(np.max(np.abs(evals[1:] - ref[1:]) / np.abs(ref[1:]))),
            "lambda0_abs_diff": float(abs(evals[0] - ref[0])),
            "max_orthonormality_error": float(np.abs(evecs.T @ (mass[:, None] * evecs) - np.eye(k)).max()),
        }
    out["all_times_s"] = {name: [round(t, 3) for t in ts] for name, ts in times.items()}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--k", type=int, default=120)
    args = parser.parse_args()
    if not DATA.is_dir():
        sys.exit(f"shared data folder {DATA} is absent: set CURVEFM_SHARED_DATA to the folder of real meshes")
    load_before = round(os.getloadavg()[0], 2)  # other processes on the machine skew every timing
    meshes = {name: bench_mesh(DATA / rel, args.k, args.repeats) for name, rel in MESHES.items()}
    machine = {
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "openblas_num_threads": os.environ.get("OPENBLAS_NUM_THREADS"),
        "load_avg_1min_before_after": [load_before, round(os.getloadavg()[0], 2)],
    }
    report = {"machine": machine, "meshes": meshes}
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    limit_blas_threads()
    main()
