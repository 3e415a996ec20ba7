"""pyFM against the default ``curvefm match`` in both directions, issue 35's protocol (prints JSON).

Pairs: FAUST tr_reg_000 -> tr_reg_011 and cat -> lion; n = 2 and 10 curves between 2n farthest points among the
vertices with ground truth, consecutive pairs joined, chosen on the source (scored source -> target) and, in a row of
their own, on the target (scored target -> source), as ``curvefm evaluate --endpoints-on``. Every map of a row is
scored on the same ground-truth rows, never at a curve's end (:func:`curvefm.evaluation.truth_to_score`), both ways;
the row's own direction is the headline. Error: mean geodesic error / sqrt(area) of the shape mapped onto.

pyFM (PyPI ``pyfmaps``, extra ``bench``), as issue 35's filer ran it: WKS plus the curves' endpoints as landmarks
(their wave kernel maps), ``preprocess(n_descr=100, k_process=120)``, ``fit(K=(50, 50))`` with its default weights,
nearest-neighbour conversion (``get_p2p``), one fit per direction; then its ``zoomout_refine`` from 50 to
``PYFM_ZOOMOUT_FINAL`` in steps of ``PYFM_ZOOMOUT_STEP`` (our ``zoomout``'s final size and step). Ours:
:func:`curvefm.matching.match` with its defaults (``curvefm match``), and with ``--refine zoomout`` / ``--refine
rhm`` (the guard's returned maps), given the same curves. ``--no-pyfm`` leaves pyFM out (its rows do not change
with our defaults) and ``--ours`` chooses our converters.

    nice python -m experiments.pyfm_both_directions [--pairs faust,cat_lion] [--counts 2,10]
        [--endpoints-on source,target] [--no-pyfm] [--ours default,zoomout,rhm]
        [--out experiments/pyfm_both_directions.json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from pyFM.functional import FunctionalMapping
from pyFM.mesh import TriMesh

from benchmarks.common import bench_store, machine, shared_data
from curvefm.evaluation import ENDPOINT_SIDES, evaluate_map, ground_truth_curves, ground_truth_for, truth_to_score
from curvefm.evaluation.ground_truth import GroundTruth
from curvefm.fmap import Hints
from curvefm.geometry import Mesh, load_mesh
from curvefm.matching import match
from curvefm.runtime import limit_blas_threads
from experiments.pyfm import PAIRS

PYFM_K = 50
PYFM_ZOOMOUT_FINAL = 120
PYFM_ZOOMOUT_STEP = 5
PYFM_EIGENPAIRS = 128  # what pyFM's preprocess computes: max(k_process, its k_descr default 128)
OURS = {"default": "nearest-neighbor", "zoomout": "zoomout", "rhm": "rhm"}
DIRECTIONS = ("source_to_target", "target_to_source")
HEADLINE = {"source": "source_to_target", "target": "target_to_source"}


def both_ways(p2p_MN: np.ndarray, p2p_NM: np.ndarray, truth: GroundTruth, mesh_M: Mesh, mesh_N: Mesh) -> dict:
    """Mean geodesic error / sqrt(area) of each map on the rows of ``truth``: M -> N measured on N, N -> M on M."""
    reverse = (truth.ids_Y, truth.ids_X)
    return {
        "source_to_target": round(evaluate_map(p2p_MN, truth, mesh_N).mean_area, 5),
        "target_to_source": round(evaluate_map(p2p_NM, reverse, mesh_M).mean_area, 5),
    }


def pyfm_maps(mesh_from: TriMesh, mesh_to: TriMesh, landmarks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """pyFM's pointwise map ``from -> to`` (``landmarks``: rows of (from, to) vertices), fitted and after ZoomOut.

    pyFM's ``FunctionalMapping(mesh1, mesh2).get_p2p()`` maps mesh2's vertices to mesh1, so the fit runs from
    ``to`` to ``from``."""
    model = FunctionalMapping(mesh_to, mesh_from)
    model.preprocess(n_descr=100, descr_type="WKS", landmarks=landmarks[:, ::-1], k_process=PYFM_ZOOMOUT_FINAL)
    model.fit(K=(PYFM_K, PYFM_K))
    steps = (PYFM_ZOOMOUT_FINAL - PYFM_K) // PYFM_ZOOMOUT_STEP
    zoomed = model.zoomout_refine(nit=steps, step=PYFM_ZOOMOUT_STEP)
    return model.get_p2p(), model.get_p2p(FM=zoomed)


def pyfm_errors(meshes: tuple[Mesh, Mesh], pyfm_meshes: tuple[TriMesh, TriMesh], curves, truth) -> dict:
    """pyFM's maps both ways (a fit each) from the curves' endpoints, before and after its ZoomOut."""
    mesh_M, mesh_N = meshes
    tri_M, tri_N = pyfm_meshes
    landmarks = Hints.from_curves(curves).landmarks
    start = time.perf_counter()
    fitted_MN, zoomed_MN = pyfm_maps(tri_M, tri_N, landmarks)
    fitted_NM, zoomed_NM = pyfm_maps(tri_N, tri_M, landmarks[:, ::-1])
    return {
        "pyfm": both_ways(fitted_MN, fitted_NM, truth, mesh_M, mesh_N),
        "pyfm_zoomout": both_ways(zoomed_MN, zoomed_NM, truth, mesh_M, mesh_N),
        "pyfm_seconds": round(time.perf_counter() - start, 1),
    }


def our_errors(meshes: tuple[Mesh, Mesh], curves, truth, labels: list[str]) -> dict:
    """``curvefm match``'s maps with the converters of :data:`OURS` named in ``labels``, their kept stage and
    seconds."""
    mesh_M, mesh_N = meshes
    out = {}
    for label in labels:
        converter = OURS[label]
        start = time.perf_counter()
        result = match(mesh_M, mesh_N, curves, converter=converter, store=bench_store())
        out[label] = both_ways(result.maps.p2p_MN, result.maps.p2p_NM, truth, mesh_M, mesh_N)
        out[f"{label}_kept"] = result.kept
        out[f"{label}_seconds"] = round(time.perf_counter() - start, 1)
    return out


def run_pair(name: str, counts: list[int], sides: list[str], with_pyfm: bool, ours: list[str]) -> list[dict]:
    data = shared_data()
    source, target = (data / p for p in PAIRS[name])
    meshes = load_mesh(source), load_mesh(target)
    truth = ground_truth_for(source, target, *meshes)
    if with_pyfm:
        pyfm_meshes = tuple(
            TriMesh(m.vertices, m.faces, area_normalize=True, center=True).process(k=PYFM_EIGENPAIRS) for m in meshes
        )
    rows = []
    for count in counts:
        for side in sides:
            curves = ground_truth_curves(*meshes, truth, count, endpoints_on=side)
            scored = truth_to_score(truth, curves, 0, side)
            row = {"pair": name, "curves": count, "endpoints_on": side, "scored_rows": len(scored)}
            if with_pyfm:
                row |= pyfm_errors(meshes, pyfm_meshes, curves, scored)
            row |= our_errors(meshes, curves, scored, ours)
            direction = HEADLINE[side]
            cells = [f"{label} {row[label][direction]}" for label in ("pyfm", "pyfm_zoomout", *ours) if label in row]
            print(f"{name} {count} curves on the {side}, {direction}: {', '.join(cells)}", file=sys.stderr, flush=True)
            rows.append(row)
    return rows


def measured_commit() -> str:
    """The commit the run measured (its defaults), with a mark when the worktree differs from it."""
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    dirty = subprocess.run(["git", "status", "--porcelain", "src"], capture_output=True, text=True).stdout.strip()
    return head + (" (src modified)" if dirty else "")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", default=",".join(PAIRS))
    parser.add_argument("--counts", default="2,10")
    parser.add_argument("--endpoints-on", default=",".join(ENDPOINT_SIDES))
    parser.add_argument("--no-pyfm", dest="pyfm", action="store_false", help="leave pyFM's maps out")
    parser.add_argument("--ours", default=",".join(OURS), help="our converters' labels (default, zoomout, rhm)")
    parser.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    args = parser.parse_args()
    limit_blas_threads(1)
    report = {
        "experiment": "pyfm_both_directions",
        "machine": machine() | {"load_avg_1min_before": round(os.getloadavg()[0], 2)},
        "commit": measured_commit(),
        "protocol": "issue 35: 2n farthest points on the endpoints_on side among vertices with ground truth, "
        "consecutive pairs joined; scored on truth_to_score's rows (never at a curve's end)",
        "error": "mean geodesic error / sqrt(area) of the shape mapped onto; headline direction: source_to_target "
        "for endpoints on the source, target_to_source for endpoints on the target",
        "pyfm": f"WKS + endpoints as landmarks, fit K=({PYFM_K}, {PYFM_K}) default weights, get_p2p; ZoomOut "
        f"{PYFM_K} -> {PYFM_ZOOMOUT_FINAL} step {PYFM_ZOOMOUT_STEP}",
        "ours": "curvefm.matching.match defaults (curvefm match), --refine zoomout / rhm",
    }
    if not args.pyfm:
        report["pyfm"] = "not run (--no-pyfm)"
    start = time.perf_counter()
    counts = [int(c) for c in args.counts.split(",")]
    sides, ours = args.endpoints_on.split(","), args.ours.split(",")
    rows = [row for name in args.pairs.split(",") for row in run_pair(name, counts, sides, args.pyfm, ours)]
    report["machine"]["load_avg_1min_after"] = round(os.getloadavg()[0], 2)
    report["seconds"] = round(time.perf_counter() - start)
    report["rows"] = rows
    text = json.dumps(report, indent=1)
    if args.out is not None:
        args.out.write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
