"""Spectral shape analysis: the first k Laplace-Beltrami eigenpairs (:class:`Basis`, always of the mesh
scaled to unit area), the eigensolver that computes them, spectral descriptors (wave kernels), and the
:class:`ShapePair` (two meshes with their bases) that maps are computed on, and an approximate
multiresolution basis for big meshes.
"""

from curvefm.spectral.basis import Basis, check_k, max_k
from curvefm.spectral.descriptors import (
    curve_function,
    energy_filters,
    multiplication_operators,
    normalised,
    wave_kernel_map_coefficients,
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
    shifted_factor,
    smallest_eigenpairs,
)
from curvefm.spectral.multires import multires_eigenpairs, prolongation
from curvefm.spectral.pair import ShapePair

__all__ = [
    "BLOCK",
    "Basis",
    "EigenError",
    "PARALLEL_MIN_VERTICES",
    "SIGMA",
    "ShapePair",
    "block_lanczos",
    "check_k",
    "curve_function",
    "energy_filters",
    "index_range",
    "log",
    "max_k",
    "multires_eigenpairs",
    "multiplication_operators",
    "normalised",
    "prolongation",
    "shifted_factor",
    "smallest_eigenpairs",
    "wave_kernel_map_coefficients",
    "wave_kernel_maps",
    "wave_kernel_signature",
]
