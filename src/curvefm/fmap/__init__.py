"""Functional maps: curve restriction, the curve-constrained solver (column-separable exact solves), the
paper's CG and an L-BFGS reference, the combined energy (curves, descriptors and landmark kernels), the
descriptor baselines' energies, function transfer through a map, and the maps' round-trip quality (no ground
truth needed).

The package exports what plugins, the service, the workers and a library user call; the solvers' building blocks
and tuning constants (column solves, ridge, parallel thresholds, the descriptor energies' internals) are imported
from their modules. The defaults of the method plugins' parameters (``DEFAULT_*``, ``FULL_SIZE_*``, ...) stay
exported: the plugins, which may import packages only, declare their parameters with them.
"""

from curvefm.fmap.baselines import (
    EXACT_MAX_K,
    balanced_weights,
    check_method_k,
    descriptor_least_squares,
    normalised_eigenvalues,
)
from curvefm.fmap.column_solve import (
    solve_both,
)
from curvefm.fmap.combined import (
    CURVES_ALONE_FROM,
    DEFAULT_COMBINED_ALPHA,
    DEFAULT_DESCRIPTOR_WEIGHT,
    DEFAULT_KERNEL_WEIGHT,
    DEFAULT_PRIOR_WEIGHT,
    FULL_SIZE_ALPHA,
    FULL_SIZE_CURVES,
    FULL_SIZE_KERNEL_WEIGHT,
    KERNEL_POINTS,
    NON_ISOMETRIC_DISTORTION,
    NON_ISOMETRIC_SPECTRA,
    SIDE_CURVES,
    CombinedMapSolver,
    curves_alone_suffice,
    curves_distortion,
)
from curvefm.fmap.landmark_prior import NO17Settings, descriptor_functions, descriptor_part, no17_maps
from curvefm.fmap.maps import EffectiveSolve, FunctionalMaps, Hints
from curvefm.fmap.reference_solvers import conjugate_gradient_solve, quasi_newton_solve
from curvefm.fmap.restriction import DEFAULT_SAMPLES, restrict, restriction_operator
from curvefm.fmap.round_trip import RoundTripQuality
from curvefm.fmap.solver import DEFAULT_ALPHA, CurveMapSolver
from curvefm.fmap.transfer import FunctionTransfer, transfer, transposed_basis
from curvefm.spectral import DEFAULT_K

__all__ = [
    "CURVES_ALONE_FROM",
    "CombinedMapSolver",
    "CurveMapSolver",
    "DEFAULT_ALPHA",
    "DEFAULT_COMBINED_ALPHA",
    "DEFAULT_DESCRIPTOR_WEIGHT",
    "DEFAULT_KERNEL_WEIGHT",
    "DEFAULT_PRIOR_WEIGHT",
    "DEFAULT_K",
    "DEFAULT_SAMPLES",
    "EXACT_MAX_K",
    "FULL_SIZE_ALPHA",
    "FULL_SIZE_CURVES",
    "FULL_SIZE_KERNEL_WEIGHT",
    "SIDE_CURVES",
    "FunctionTransfer",
    "EffectiveSolve",
    "FunctionalMaps",
    "Hints",
    "KERNEL_POINTS",
    "NO17Settings",
    "NON_ISOMETRIC_DISTORTION",
    "NON_ISOMETRIC_SPECTRA",
    "RoundTripQuality",
    "balanced_weights",
    "check_method_k",
    "conjugate_gradient_solve",
    "curves_alone_suffice",
    "curves_distortion",
    "descriptor_functions",
    "descriptor_least_squares",
    "descriptor_part",
    "no17_maps",
    "normalised_eigenvalues",
    "quasi_newton_solve",
    "restrict",
    "restriction_operator",
    "solve_both",
    "transfer",
    "transposed_basis",
]
