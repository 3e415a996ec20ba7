"""Process-wide settings that only an entry point makes; importing curvefm changes nothing in a process.

The CLI (and so ``curvefm serve`` and ``curvefm worker``), the tests and the benchmarks call
:func:`limit_blas_threads` when they start. curvefm parallelises explicitly (two map directions on two threads,
spectrum slices in two processes, one job per worker); OpenBLAS's own threads on top of that oversubscribe the
cores: on a busy two-core machine they made 120 x 120 factorisations 10-60x slower.
"""

from __future__ import annotations

import os

from threadpoolctl import threadpool_limits

BLAS_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def limit_blas_threads(threads: int = 1) -> None:
    """Run BLAS and OpenMP with ``threads`` threads in this process and the processes it starts (slice
    workers, RQ work horses). A user's own setting of any of :data:`BLAS_VARIABLES` wins."""
    if any(variable in os.environ for variable in BLAS_VARIABLES):
        return
    for variable in BLAS_VARIABLES:
        os.environ[variable] = str(threads)
    threadpool_limits(threads)
