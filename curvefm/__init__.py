"""curvefm: interactive curve-constrained functional maps between 3D shapes."""

import os

# curvefm parallelises explicitly (two map directions on two threads, spectrum slices in two processes, one
# job per worker). OpenBLAS's own threads on top of that oversubscribe the cores: on a busy two-core machine
# they made 120 x 120 factorisations 10-60x slower. Set before numpy is first imported; a user's own setting wins.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

__version__ = "0.1.0"
