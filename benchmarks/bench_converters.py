"""Time and error of each converter from the 10-curve maps, on FAUST 000 -> 011 and cat -> lion (prints JSON).

The 10 curves follow the core issue's protocol (:mod:`curvefm.evaluation.protocol`); every converter starts from the
same two functional maps (k = 120, the session defaults). Errors are mean geodesic error / sqrt(area of the
mesh each map lands on), both directions. ``seconds`` is the converter alone (bases and curves are ready), the
median of ``--repeat`` runs. ``worker`` runs ``rhm`` with its defaults on FAUST as a refinement job on the in-process
queue (the same job function RQ workers run) and records the wall time and the progress reports seen.

``--scan-level L`` (2: 110,210 vertices) also runs the refiners on FAUST tr_reg_000 -> 011 subdivided L times
(benchmarks/bench_scan.py; the pair shares its connectivity, errors on the original 6,890 vertices), each on
every vertex (``dense_up_to`` above the size) and with its default, which at that size iterates on samples
(ZoomOut, ICP) or decimated copies (RHM) and matches every vertex once at the end. RHM is run with its default
only: on every vertex of the 110k pair it took about 30 s an iteration (two factorisations of that size), so
about an hour for the iterations it needs.

    python -m benchmarks.bench_converters [--repeat 1] [--variants] [--scan-level 2] [--no-faust-and-cat]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time

import numpy as np

from benchmarks.bench_scan import PAIR, subdivided
from benchmarks.common import bench_store, machine, shared_data
from curvefm import registry
from curvefm.evaluation import GroundTruth, evaluate_map, ground_truth_curves, ground_truth_for, score
from curvefm.fmap import DEFAULT_ALPHA, DEFAULT_K, DEFAULT_SAMPLES
from curvefm.geometry import load_mesh
from curvefm.matching import MatchResult, match
from curvefm.runtime import limit_blas_threads
from curvefm.session import CurveRecord, CurveSpec, SessionRecord
from curvefm.store import Store
from curvefm.workers.embedded import EmbeddedQueue

PAIRS = {
    "faust_000_011": ("faust/tr_reg_000.off", "faust/tr_reg_011.off"),
    "cat_lion": ("nonisometric/pyfm_cat_lion/cat-00.off", "nonisometric/pyfm_cat_lion/lion-00.off"),
}
CONVERTERS = [
    ("nearest-neighbor", {}),
    ("icp", {}),
    ("zoomout", {}),
    ("zoomout", {"samples": 2000}),
    ("rhm", {}),
]
EVERY_VERTEX = {"dense_up_to": 10**9}
SCAN_CONVERTERS = [
    ("zoomout", EVERY_VERTEX),
    ("zoomout", {}),
    ("icp", EVERY_VERTEX),
    ("icp", {}),
    ("rhm", {}),
]
VARIANTS = [
    ("zoomout", {"embedding": "both"}),
    ("zoomout", {"k_init": 120, "k_final": 200}),
    ("icp", {"k": 50, "k_image": 50}),
    ("rhm", {"init": "nearest-neighbor"}),
    ("rhm", {"projection": "triangle"}),
]


def errors(result: MatchResult, maps, truth) -> dict:
    reverse = (truth.ids_Y, truth.ids_X)
    return {
        "source_to_target": evaluate_map(maps.p2p_MN, truth, result.pair.mesh_N).mean_area,
        "target_to_source": evaluate_map(maps.p2p_NM, reverse, result.pair.mesh_M).mean_area,
    }


def run_converter(result: MatchResult, truth, name: str, params: dict, repeat: int) -> dict:
    plugin, parsed = registry.load("converter", name, params)
    times, maps, last = [], None, ""

    def progress(fraction: float, message: str) -> None:
        nonlocal last
        last = message

    for _ in range(repeat):
        start = time.perf_counter()
        maps = plugin.run(result.pair, result.fmaps, parsed, progress)
        times.append(time.perf_counter() - start)
    return {"converter": name, "params": params, "seconds": statistics.median(times), "last_message": last} | errors(
        result, maps, truth
    )


def session_record(store: Store, result: MatchResult, curves) -> dict:
    """The refinement job's input: a session snapshot with the curves as explicit file-id paths."""
    mesh_M, mesh_N = result.pair.meshes
    records = []
    for i, (path_M, path_N) in enumerate(curves):
        ids_M, ids_N = mesh_M.file_ids[path_M].tolist(), mesh_N.file_ids[path_N].tolist()
        spec = CurveSpec(source=ids_M, target=ids_N, explicit=True)
        records.append(CurveRecord(id=f"c{i}", spec=spec, tracer="geodesic", path_source=ids_M, path_target=ids_N))
    return SessionRecord(
        id="bench",
        source=store.put_mesh(mesh_M),
        target=store.put_mesh(mesh_N),
        k=DEFAULT_K,
        alpha=DEFAULT_ALPHA,
        samples=DEFAULT_SAMPLES,
        tracer="geodesic",
        basis_plugin="laplace-beltrami",
        basis_params={"laplacian": "cotangent"},
        curves=records,
        created_at=time.time(),
        updated_at=time.time(),
    ).model_dump()


def run_worker_job(store: Store, result: MatchResult, curves, truth) -> dict:
    """``rhm`` (defaults) as a refine job on the in-process queue, polled like the API polls it."""
    queue = EmbeddedQueue(store.root, max_workers=1)
    kwargs = {"data_dir": str(store.root), "session": session_record(store, result, curves), "converter": "rhm"}
    start = time.perf_counter()
    try:
        job_id = queue.submit("refine", kwargs).id
        reports = []
        while (info := queue.get(job_id)).state not in ("finished", "failed", "canceled"):
            if not reports or reports[-1] != (info.progress, info.message):
                reports.append((info.progress, info.message))
            time.sleep(0.1)
    finally:
        queue.close()
    seconds = time.perf_counter() - start
    out = {"converter": "rhm", "state": info.state, "wall_seconds": seconds, "progress_reports": len(reports)}
    if info.state != "finished":
        return out | {"error": info.error.message if info.error else info.message}
    p2p_file = np.load(store.root / "results" / job_id / "p2p_source_to_target.npy")
    mesh_M, mesh_N = result.pair.meshes
    p2p_MN = mesh_N.internal_ids(p2p_file[mesh_M.file_ids])
    return out | {"source_to_target": evaluate_map(p2p_MN, truth, mesh_N).mean_area}


def scan_pair(level: int, repeat: int) -> dict:
    """The refiners on the subdivided FAUST pair from its 10-curve maps (default method), every vertex against
    the defaults."""
    meshes = [subdivided(name, level) for name in PAIR]
    original = np.arange(6890)
    truth = GroundTruth(meshes[0].internal_ids(original), meshes[1].internal_ids(original), "identity", True)
    curves = ground_truth_curves(meshes[0], meshes[1], truth, 10)
    start = time.perf_counter()
    result = match(meshes[0], meshes[1], curves, store=bench_store())
    entry = {"vertices": meshes[0].n_vertices, "match_s": round(time.perf_counter() - start, 1)}
    entry["start"] = {d: errors["mean_area"] for d, errors in score(result, truth).items()}
    entry["converters"] = []
    for name, params in SCAN_CONVERTERS:
        entry["converters"].append(run_converter(result, truth, name, params, repeat))
        print(json.dumps(entry["converters"][-1]), file=sys.stderr, flush=True)
    return entry


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=1, help="runs per converter (median time)")
    parser.add_argument("--variants", action="store_true", help="also run non-default variants (slow: minutes)")
    parser.add_argument("--no-worker", action="store_true", help="skip the refinement job on the in-process queue")
    parser.add_argument("--scan-level", type=int, default=None, help="also the subdivided FAUST pair (2: 110k)")
    parser.add_argument("--no-faust-and-cat", action="store_true", help="skip the two 7k pairs")
    args = parser.parse_args()
    data, store = shared_data(), bench_store()
    report = {"machine": machine(), "curves": 10, "k": 120, "pairs": {}}
    report["machine"]["load_avg_1min_before"] = round(os.getloadavg()[0], 2)
    for pair, (source, target) in ({} if args.no_faust_and_cat else PAIRS).items():
        mesh_M, mesh_N = load_mesh(data / source), load_mesh(data / target)
        truth = ground_truth_for(data / source, data / target, mesh_M, mesh_N)
        curves = ground_truth_curves(mesh_M, mesh_N, truth, 10)
        result = match(mesh_M, mesh_N, curves, store=store)
        entry = {"vertices": [mesh_M.n_vertices, mesh_N.n_vertices], "start": score(result, truth)}
        entry["start"] = {d: entry["start"][d]["mean_area"] for d in entry["start"]}
        runs = CONVERTERS + (VARIANTS if args.variants else [])
        entry["converters"] = [run_converter(result, truth, name, params, args.repeat) for name, params in runs]
        if not args.no_worker and pair == "faust_000_011":
            entry["worker"] = run_worker_job(store, result, curves, truth)
        report["pairs"][pair] = entry
    if args.scan_level is not None:
        report["pairs"][f"faust_000_011_subdivided_{args.scan_level}"] = scan_pair(args.scan_level, args.repeat)
    report["machine"]["load_avg_1min_after"] = round(os.getloadavg()[0], 2)
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    limit_blas_threads()
    main()
