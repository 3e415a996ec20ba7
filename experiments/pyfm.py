"""Our descriptor baselines (OBCS12, NO17) against pyFM itself on the same pairs and landmarks (prints JSON).

Pairs: FAUST tr_reg_000 -> tr_reg_011 and cat -> lion. Landmarks: the endpoints of the core protocol's
n curves (2n farthest points among ground-truth vertices, :func:`curvefm.evaluation.ground_truth_curves`),
n = 1, 2, 5, 10. pyFM (PyPI ``pyfmaps``, extra ``bench``): WKS plus the landmarks' wave kernel maps,
``preprocess(n_descr=100, k_process=120)``, ``fit(K=(50, 50))`` with its default weights (``no17``'s
reference) and with ``w_dcomm=0`` (``obcs12``'s: descriptors and Laplacian commutativity only), then its
nearest-neighbour conversion. Ours: the method plugins with their defaults, converted by nearest neighbours
from the single map (as pyFM) and from both maps (the ``nearest-neighbor`` converter). Errors: the source ->
target map, mean geodesic error / sqrt(area of the target), never at a curve's end
(:func:`curvefm.evaluation.truth_to_score`; before 2026-11-28 the ends were scored too). Both directions, issue 35's
protocol, the default method and pyFM's ZoomOut: ``experiments/pyfm_both_directions.py``.

    pip install -e ".[bench]"; python -m experiments.pyfm [--curves 1,2,5,10] [--pairs faust,cat_lion]
"""

from __future__ import annotations

import argparse
import json
import time

from pyFM.functional import FunctionalMapping
from pyFM.mesh import TriMesh

from benchmarks.common import bench_store, machine, shared_data
from curvefm import registry
from curvefm.evaluation import evaluate_map, ground_truth_curves, ground_truth_for, truth_to_score
from curvefm.fmap import Hints
from curvefm.geometry import load_mesh
from curvefm.matching import pair_with_basis_size
from curvefm.pointwise import pointwise_from_both, pointwise_from_fmap
from curvefm.runtime import limit_blas_threads

PAIRS = {
    "faust": ("faust/tr_reg_000.off", "faust/tr_reg_011.off"),
    "cat_lion": ("nonisometric/pyfm_cat_lion/cat-00.off", "nonisometric/pyfm_cat_lion/lion-00.off"),
}
PYFM_REFERENCE = {"no17": {}, "obcs12": {"w_dcomm": 0.0}}


def pyfm_error(mesh_M, mesh_N, landmarks, truth, fit: dict) -> tuple[float, float]:
    """pyFM's source -> target map: fitted from N to M so that its ``get_p2p`` maps M's vertices to N."""
    start = time.perf_counter()
    target, source = (TriMesh(m.vertices, m.faces, area_normalize=True, center=True) for m in (mesh_N, mesh_M))
    model = FunctionalMapping(target, source)
    model.preprocess(n_descr=100, descr_type="WKS", landmarks=landmarks[:, ::-1], k_process=120)
    model.fit(K=(50, 50), **fit)
    p2p_MN = model.get_p2p()
    return evaluate_map(p2p_MN, truth, mesh_N).mean_area, time.perf_counter() - start


def our_errors(pair, hints, truth, method: str) -> dict:
    start = time.perf_counter()
    plugin, params = registry.load("method", method)
    maps = plugin.run(pair.truncated(120), hints, params)
    seconds = time.perf_counter() - start
    single = pointwise_from_fmap(maps.C_NM, pair.basis_N, pair.basis_M)
    both = pointwise_from_both(maps.C_NM, maps.C_MN, pair.basis_N, pair.basis_M)
    return {
        "single": evaluate_map(single, truth, pair.mesh_N).mean_area,
        "both": evaluate_map(both, truth, pair.mesh_N).mean_area,
        "seconds": seconds,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--curves", default="1,2,5,10")
    parser.add_argument("--pairs", default=",".join(PAIRS))
    args = parser.parse_args()
    limit_blas_threads()
    data, store = shared_data(), bench_store()
    rows = []
    for name in args.pairs.split(","):
        source, target = (data / p for p in PAIRS[name])
        mesh_M, mesh_N = load_mesh(source), load_mesh(target)
        truth = ground_truth_for(source, target, mesh_M, mesh_N)
        pair = pair_with_basis_size(store, (mesh_M, mesh_N), 120)
        for n in (int(c) for c in args.curves.split(",")):
            curves = ground_truth_curves(mesh_M, mesh_N, truth, n)
            hints, scored = Hints.from_curves(curves), truth_to_score(truth, curves)
            for method, fit in PYFM_REFERENCE.items():
                reference, seconds = pyfm_error(mesh_M, mesh_N, hints.landmarks, scored, fit)
                ours = our_errors(pair, hints, scored, method)
                row = {
                    "pair": name,
                    "curves": n,
                    "landmarks": len(hints.landmarks),
                    "method": method,
                    "pyfm": reference,
                    "pyfm_seconds": seconds,
                    "ours_single": ours["single"],
                    "ours_both": ours["both"],
                    "ours_seconds": ours["seconds"],
                    "ratio_single": ours["single"] / reference,
                }
                rows.append(row)
                print(json.dumps(row), flush=True)
    print(json.dumps({"machine": machine(), "results": rows}, indent=2))


if __name__ == "__main__":
    main()
