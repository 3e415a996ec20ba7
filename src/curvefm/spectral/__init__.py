"""Spectral shape analysis: the first k Laplace-Beltrami eigenpairs (:class:`Basis`, always of the mesh
scaled to unit area), the default basis that computes them (:func:`laplace_beltrami_basis`, exact or
multiresolution on big meshes) and its eigensolvers, spectral descriptors (wave kernels), and the
:class:`ShapePair` (two meshes with their bases) that maps are computed on.

The eigensolvers' tuning constants and building blocks (``SIGMA``, ``BLOCK``, ``block_lanczos``, ...) stay in
:mod:`curvefm.spectral.eigensolver` and :mod:`curvefm.spectral.multires`.
"""

from curvefm.spectral.basis import DEFAULT_K, Basis, check_k, max_k
from curvefm.spectral.descriptors import (
    Quadrature,
    curve_function,
    energy_filters,
    multiplication_operators,
    normalised,
    scan_quadrature,
    wave_kernel_map_coefficients,
    wave_kernel_maps,
    wave_kernel_signature,
)
from curvefm.spectral.eigensolver import EigenError, smallest_eigenpairs
from curvefm.spectral.laplace_beltrami import (
    DEFAULT_BASIS,
    LaplaceBeltramiParams,
    laplace_beltrami_basis,
    laplace_beltrami_storage_params,
)
from curvefm.spectral.multires import multires_eigenpairs
from curvefm.spectral.shape_pair import ShapePair

__all__ = [
    "DEFAULT_BASIS",
    "DEFAULT_K",
    "Basis",
    "EigenError",
    "LaplaceBeltramiParams",
    "Quadrature",
    "ShapePair",
    "check_k",
    "curve_function",
    "energy_filters",
    "laplace_beltrami_basis",
    "laplace_beltrami_storage_params",
    "max_k",
    "multires_eigenpairs",
    "multiplication_operators",
    "normalised",
    "scan_quadrature",
    "smallest_eigenpairs",
    "wave_kernel_map_coefficients",
    "wave_kernel_maps",
    "wave_kernel_signature",
]
