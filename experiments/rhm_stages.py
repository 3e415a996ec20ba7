"""Where does RHM's map come from? Its stages on issue 35's protocol (issue 35: RHM from 10 curves ended worse than
from 2 on cat -> lion with the endpoints on the lion).

n curves between 2n farthest points chosen on the ``endpoints_on`` side among vertices with ground truth, consecutive
pairs joined, the default method's (``combined``) functional maps at k = 120. Each row records, as mean geodesic error
/ sqrt(area) source -> target, target -> source and their mean, at the ground-truth rows that are no curve's end
(:func:`curvefm.evaluation.truth_to_score`): the maps ``curvefm match`` hands out (``start``,
:func:`curvefm.matching.handed_out`, the guard's reference), ``zoomout`` through the guard (``zoomout_returned``), and
per RHM variant its ZoomOut start, which maps anchor it (``zoomout``: the start, the guard accepting it; ``nn``: the
handed-out maps), RHM's own map, its iterations, what the guard of :func:`curvefm.matching.convert` would return and
the seconds. Variants are :class:`~curvefm.plugins.rhm.RhmParams` overrides, plus ``from_anchor``: RHM started from
its anchor maps instead of its ZoomOut start.
Prints one JSON object per row (experiments/rhm_stages.json holds the rows of docs/accuracy.md).

    nice python -m experiments.rhm_stages '[["SOURCE", "TARGET", "target", 10], ...]' '{"default": {}}'
"""

from __future__ import annotations

import json
import sys
import time

from curvefm import registry
from curvefm.evaluation import ground_truth_curves, score_maps, truth_to_score
from curvefm.fmap import DEFAULT_K, Hints
from curvefm.matching import convert, handed_out
from curvefm.plugins.rhm import REFINER, RhmParams, RhmStart, prepare_shape
from curvefm.pointwise import PointwiseMaps, compare, measure
from curvefm.runtime import limit_blas_threads
from experiments.common import ground_truth_pair


def errors(pair, maps, scored) -> list[float]:
    """Source -> target, target -> source and their mean."""
    both = score_maps(pair, maps, scored)
    there, back = both["source_to_target"]["mean_area"], both["target_to_source"]["mean_area"]
    return [round(there, 5), round(back, 5), round((there + back) / 2, 5)]


def rhm_stages(pair, fmaps, curves, scored, start, overrides: dict) -> dict:
    """RHM's start, anchor, own map and what the guard would return, for one variant."""
    overrides = dict(overrides)
    from_anchor = overrides.pop("from_anchor", False)
    params = RhmParams(**overrides)
    began = time.time()
    rhm_start = REFINER.start(pair, fmaps, params, curves=curves)
    anchor = "zoomout" if rhm_start.anchor is rhm_start.maps else "nn" if rhm_start.anchor is not None else "none"
    if from_anchor:
        rhm_start = RhmStart(rhm_start.anchor, rhm_start.pins, anchor=rhm_start.anchor)
    shape_M, shape_N = prepare_shape(pair.mesh_M, params), prepare_shape(pair.mesh_N, params)
    state = REFINER.begin(rhm_start.maps, shape_M, shape_N, rhm_start.pins, rhm_start.anchor)
    REFINER.iterate(state, params, lambda *_: None)
    rhm = PointwiseMaps(p2p_NM=state.NM.p2p, p2p_MN=state.MN.p2p)
    reference = measure(pair, start, curves)
    worse = compare(measure(pair, rhm, curves), reference)
    start_worse = compare(measure(pair, rhm_start.maps, curves), reference)
    kept = "refined" if not worse else "initial" if start_worse else "stopped"
    returned = {"refined": rhm, "stopped": rhm_start.maps, "initial": start}[kept]
    return {
        "zoomout_start": errors(pair, rhm_start.maps, scored),
        "anchor": anchor,
        "rhm": errors(pair, rhm, scored),
        "iterations": len(state.energies),
        "kept": kept,
        "worse": worse,
        "returned": errors(pair, returned, scored),
        "s": round(time.time() - began),
    }


def row(source: str, target: str, side: str, count: int, variants: dict, with_zoomout: bool = True) -> dict:
    """One row: the handed-out maps, ``zoomout`` through the guard (unless not ``with_zoomout``) and every variant."""
    pair, truth = ground_truth_pair(source, target)
    curves = ground_truth_curves(pair.mesh_M, pair.mesh_N, truth, count, endpoints_on=side)
    scored = truth_to_score(truth, curves, 0, side)
    method, method_params = registry.load("method", "combined", None)
    fmaps = method.run(pair.truncated(DEFAULT_K), Hints.from_curves(curves), method_params, lambda *_: None)
    start = handed_out(pair, fmaps)
    out = {"pair": f"{source}->{target}", "side": side, "curves": count, "start": errors(pair, start, scored)}
    if with_zoomout:
        zoomout, zoomout_params = registry.load("converter", "zoomout", None)
        returned = convert(pair, fmaps, zoomout, zoomout_params, paths=curves)
        out["zoomout_returned"] = [*errors(pair, returned.maps, scored), returned.kept]
    for name, overrides in variants.items():
        out[name] = rhm_stages(pair, fmaps, curves, scored, start, overrides)
    return out


if __name__ == "__main__":
    limit_blas_threads(1)
    for source, target, side, count in json.loads(sys.argv[1]):
        print(json.dumps(row(source, target, side, count, json.loads(sys.argv[2]))), flush=True)
