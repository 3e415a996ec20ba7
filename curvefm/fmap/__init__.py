"""Functional maps: curve restriction, the curve-constrained solver (column-separable exact solves), the
paper's CG and an L-BFGS reference, the combined energy (curves, descriptors and landmark kernels), the
descriptor baselines' energies, function transfer through a map, and the maps' round-trip quality (no ground
truth needed).
"""

from curvefm.fmap.baselines import (
    EXACT_MAX_K,
    DescriptorEnergy,
    balanced_weights,
    check_method_k,
    descriptor_least_squares,
    effective_count,
    lbfgs,
    normalised_eigenvalues,
)
from curvefm.fmap.column_solve import (
    PARALLEL_MIN_SIZE,
    RIDGE,
    Prior,
    column_diagonals,
    column_ridge,
    solve_both,
    solve_columns,
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
    CombinedMapSolver,
    curves_alone_suffice,
    landmark_distortion,
    spectral_mismatch,
)
from curvefm.fmap.landmark_prior import NO17Settings, descriptor_functions, descriptor_part, landmark_maps, no17_maps
from curvefm.fmap.maps import FunctionalMaps, Hints, curve_endpoints
from curvefm.fmap.reference_solvers import conjugate_gradient_solve, quasi_newton_solve
from curvefm.fmap.restriction import DEFAULT_SAMPLES, resample, restrict, restriction_operator
from curvefm.fmap.round_trip import RoundTrip, RoundTripQuality
from curvefm.fmap.solver import DEFAULT_ALPHA, DEFAULT_K, CurveMapSolver, CurveTerm
from curvefm.fmap.transfer import FunctionTransfer, transfer

__all__ = [
    "CURVES_ALONE_FROM",
    "CombinedMapSolver",
    "CurveMapSolver",
    "CurveTerm",
    "DEFAULT_ALPHA",
    "DEFAULT_COMBINED_ALPHA",
    "DEFAULT_DESCRIPTOR_WEIGHT",
    "DEFAULT_KERNEL_WEIGHT",
    "DEFAULT_PRIOR_WEIGHT",
    "DEFAULT_K",
    "DEFAULT_SAMPLES",
    "DescriptorEnergy",
    "EXACT_MAX_K",
    "FULL_SIZE_ALPHA",
    "FULL_SIZE_CURVES",
    "FULL_SIZE_KERNEL_WEIGHT",
    "FunctionTransfer",
    "FunctionalMaps",
    "Hints",
    "KERNEL_POINTS",
    "NO17Settings",
    "NON_ISOMETRIC_DISTORTION",
    "NON_ISOMETRIC_SPECTRA",
    "PARALLEL_MIN_SIZE",
    "Prior",
    "RIDGE",
    "RoundTrip",
    "RoundTripQuality",
    "balanced_weights",
    "check_method_k",
    "column_diagonals",
    "column_ridge",
    "conjugate_gradient_solve",
    "curve_endpoints",
    "curves_alone_suffice",
    "descriptor_functions",
    "descriptor_least_squares",
    "descriptor_part",
    "effective_count",
    "landmark_distortion",
    "landmark_maps",
    "lbfgs",
    "no17_maps",
    "normalised_eigenvalues",
    "quasi_newton_solve",
    "resample",
    "restrict",
    "restriction_operator",
    "solve_both",
    "solve_columns",
    "spectral_mismatch",
    "transfer",
]
