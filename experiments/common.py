"""Shared helpers of the experiments (tuning studies): pairs held out of the reproduce suite, the ``--pairs`` /
``--datasets`` selection, and ``curvefm evaluate``'s ground-truth-curve protocol over a set of pairs. The data
location, cached bases and the machine record come from :mod:`benchmarks.common`."""

import argparse
import itertools
import sys

import numpy as np

from benchmarks.common import bench_store, shared_data
from curvefm.evaluation import ground_truth_for
from curvefm.evaluation.ground_truth import GroundTruth
from curvefm.evaluation.reproduce.datasets import DATASETS, FULL_PAIRS, Pair
from curvefm.geometry import load_mesh
from curvefm.spectral import ShapePair

HELD_OUT_PAIRS = (  # pairs the reproduce suite does not hold, to check rules chosen on it
    Pair("faust", "faust/tr_reg_060.off", "faust/tr_reg_071.off"),
    Pair("faust", "faust/tr_reg_080.off", "faust/tr_reg_091.off"),
    Pair("faust", "faust/tr_reg_010.off", "faust/tr_reg_051.off"),
    Pair("tosca", "tosca/dog0.off", "tosca/dog2.off"),
    Pair("tosca", "tosca/horse0.off", "tosca/horse5.off"),
    Pair("tosca", "tosca/gorilla1.off", "tosca/gorilla5.off"),
    Pair("tosca", "tosca/michael0.off", "tosca/michael1.off"),
    Pair("tosca-cross", "tosca/cat0.off", "tosca/dog0.off"),
    Pair("tosca-cross", "tosca/horse0.off", "tosca/wolf0.off"),
    Pair("tosca-cross", "tosca/dog2.off", "tosca/horse5.off"),
    Pair("tosca-cross", "tosca/michael0.off", "tosca/gorilla5.off"),
    Pair("tosca-cross", "tosca/victoria0.off", "tosca/david1.off"),
)


def add_pair_arguments(parser: argparse.ArgumentParser) -> None:
    """``--pairs suite|held-out`` (the reproduce suite's pairs or :data:`HELD_OUT_PAIRS`) and ``--datasets``."""
    parser.add_argument("--pairs", choices=("suite", "held-out"), default="suite")
    parser.add_argument("--datasets", nargs="+", default=list(DATASETS), choices=list(DATASETS))


def chosen_pairs(args: argparse.Namespace) -> list[Pair]:
    """The pairs :func:`add_pair_arguments`'s options select."""
    return [p for p in (FULL_PAIRS if args.pairs == "suite" else HELD_OUT_PAIRS) if p.dataset in args.datasets]


def ground_truth_pair(source: str, target: str, k: int = 120):
    """``(ShapePair, GroundTruth)`` for two meshes of the shared data folder (paths relative to it), with
    bases of k functions from :func:`bench_store`."""
    data, store = shared_data(), bench_store()
    M, N = load_mesh(data / source), load_mesh(data / target)
    truth = ground_truth_for(data / source, data / target, M, N)
    return ShapePair(M, N, store.ensure_basis(M, k), store.ensure_basis(N, k)), truth


def ground_truth_rows(pairs, counts, errors_for) -> list[dict]:
    """``{"pair", "curves", "errors"}`` per pair and curve count, ``errors = errors_for(pair, truth, curves)`` for
    ``curvefm evaluate``'s ground-truth curves (2n farthest points among the vertices with a known partner,
    consecutive pairs joined); progress on stderr."""
    from curvefm.evaluation import ground_truth_curves

    rows = []
    for (source, target), count in itertools.product(pairs, counts):
        pair, truth = ground_truth_pair(source, target)
        curves = ground_truth_curves(pair.mesh_M, pair.mesh_N, truth, count)
        rows.append({"pair": f"{source} -> {target}", "curves": count, "errors": errors_for(pair, truth, curves)})
        print(f"{source} -> {target}, {count} curves done", file=sys.stderr, flush=True)
    return rows


def truth_away_from_ends(truth: GroundTruth, curves) -> GroundTruth:
    """The ground-truth rows at neither end of any curve (on either shape): a map is never scored at the points
    the user gave, which the refiners pin."""
    ends_M = [path[i] for path, _ in curves for i in (0, -1)]
    ends_N = [path[i] for _, path in curves for i in (0, -1)]
    keep = ~np.isin(truth.ids_X, ends_M) & ~np.isin(truth.ids_Y, ends_N)
    return GroundTruth(truth.ids_X[keep], truth.ids_Y[keep], truth.kind, truth.dense)
