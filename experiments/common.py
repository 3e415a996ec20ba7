"""Shared helpers of the experiments (tuning studies): the ``--pairs`` / ``--datasets`` / ``--names`` selection of
the reproduce suite's pairs (to choose on) or the pairs held out of it (``HELD_OUT_PAIRS``, to check a choice), and
``curvefm evaluate``'s ground-truth-curve protocol over a set of pairs. The data location, cached bases and the
machine record come from :mod:`benchmarks.common`."""

import argparse
import itertools
import sys

from benchmarks.common import bench_store, shared_data
from curvefm.evaluation import ground_truth_for
from curvefm.evaluation.reproduce.datasets import DATASETS, FULL_PAIRS, HELD_OUT_PAIRS, Pair
from curvefm.geometry import load_mesh
from curvefm.spectral import ShapePair


def add_pair_arguments(parser: argparse.ArgumentParser) -> None:
    """``--pairs suite|held-out`` (the reproduce suite's pairs, to choose on, or :data:`HELD_OUT_PAIRS`, to check a
    choice), ``--datasets`` and ``--names``."""
    parser.add_argument("--pairs", choices=("suite", "held-out"), default="suite")
    parser.add_argument("--datasets", nargs="+", default=list(DATASETS), choices=list(DATASETS))
    parser.add_argument("--names", nargs="+", default=None, help="pair names, in this order (default: every pair)")


def chosen_pairs(args: argparse.Namespace) -> list[Pair]:
    """The pairs :func:`add_pair_arguments`'s options select."""
    pool = [p for p in (FULL_PAIRS if args.pairs == "suite" else HELD_OUT_PAIRS) if p.dataset in args.datasets]
    return pool if args.names is None else [p for name in args.names for p in pool if p.name == name]


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
