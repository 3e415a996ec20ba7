"""benchmarks/bench_suggestions.py with the map's size grown with the curves' length (issue 35).

Sets :data:`curvefm.fmap.combined.SIZE_GROWTH` and ``SIZE_WEIGHTS`` for every solver the benchmark builds, then runs
it with the remaining arguments (docs/experiments/map-size.md, "A size that grows with the curves"):

    python -m experiments.map_size_growth --growth 1 --weights interpolated [bench_suggestions options]
"""

from __future__ import annotations

import argparse
import sys

from benchmarks import bench_suggestions
from curvefm.fmap import combined
from curvefm.runtime import limit_blas_threads


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--growth", type=float, required=True)
    parser.add_argument("--weights", choices=("interpolated", "full"), default="interpolated")
    args, rest = parser.parse_known_args()
    combined.SIZE_GROWTH, combined.SIZE_WEIGHTS = args.growth, args.weights
    sys.argv = [sys.argv[0], *rest]
    limit_blas_threads()
    bench_suggestions.main()


if __name__ == "__main__":
    main()
