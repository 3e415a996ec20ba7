"""RHM with more from the curves (issue 35): experiments/rhm_stages.py's rows (same protocol, same figures per
variant) without the ZoomOut converter's row. Variants are :class:`~curvefm.plugins.rhm.RhmParams` overrides, e.g.
``curve_band`` (an inner curve vertex whose image lies farther than this from the partner curve goes to the partner
curve; the option existed at commit 0b78d7b and was removed, not adopted), ``anchor_radius`` and ``pin_weight``.
Prints one JSON object per row (experiments/rhm_curve_band.json holds the rows of docs/accuracy.md).

    nice python -m experiments.rhm_curve_band '[["SOURCE", "TARGET", "target", 10]]' '{"pin0": {"pin_weight": 0}}'
"""

from __future__ import annotations

import json
import sys

from curvefm.runtime import limit_blas_threads
from experiments.rhm_stages import row

if __name__ == "__main__":
    limit_blas_threads(1)
    for source, target, side, count in json.loads(sys.argv[1]):
        print(json.dumps(row(source, target, side, count, json.loads(sys.argv[2]), with_zoomout=False)), flush=True)
