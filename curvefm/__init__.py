"""curvefm: interactive curve-constrained functional maps between 3D shapes."""

import os
import sys

# curvefm parallelises explicitly (two map directions on two threads, spectrum slices in two processes, one
# job per worker). OpenBLAS's own threads on top of that oversubscribe the cores: on a busy two-core machine
# they made 120 x 120 factorisations 10-60x slower. A user's own setting wins.
_BLAS_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
if not any(variable in os.environ for variable in _BLAS_VARIABLES):
    for _variable in _BLAS_VARIABLES:
        os.environ[_variable] = "1"
    if "numpy" in sys.modules:  # too late for the variables to take effect: limit the loaded BLAS instead
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)

__version__ = "0.1.0"
