"""Spectral shape analysis: the first k Laplace-Beltrami eigenpairs (:class:`Basis`, always of the mesh
scaled to unit area), the eigensolver that computes them, and spectral descriptors (wave kernels).
"""

from curvefm.spectral.basis import Basis, check_k, max_k
from curvefm.spectral.descriptors import (
    curve_function,
    multiplication_operators,
    normalised,
    wave_kernel_maps,
    wave_kernel_signature,
)
from curvefm.spectral.eigensolver import (
    BLOCK,
    PARALLEL_MIN_VERTICES,
    SIGMA,
    EigenError,
    block_lanczos,
    index_range,
    log,
    smallest_eigenpairs,
)

__all__ = [
    "BLOCK",
    "Basis",
    "EigenError",
    "PARALLEL_MIN_VERTICES",
    "SIGMA",
    "block_lanczos",
    "check_k",
    "curve_function",
    "index_range",
    "log",
    "max_k",
    "multiplication_operators",
    "normalised",
    "smallest_eigenpairs",
    "wave_kernel_maps",
    "wave_kernel_signature",
]
