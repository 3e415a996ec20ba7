"""Method plugins ``combined`` (the default), ``curves``, ``obcs12`` and ``no17``: functional maps from curves
or landmarks.

See :mod:`curvefm.fmap.combined` and :mod:`curvefm.fmap.baselines` for the energies. The descriptor baselines
follow pyFM 1.3's setup:
wave kernel signatures and wave kernel maps at the landmarks from the first ``spectrum`` eigenpairs, a map
of size ``k`` (smaller than ours: descriptor methods degrade in large bases, see docs/results.md), each term
divided by its typical size (:func:`curvefm.fmap.balanced_weights`). What made them as accurate as pyFM
(``experiments/pyfm.py``; docs/accuracy.md, "Baselines against pyFM"): that normalisation, which lets redundant
descriptors count once, and energies kept two filter widths inside the spectrum; the exact solve (no17)
and using every descriptor's operator changed little.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from curvefm.errors import InvalidInput
from curvefm.fmap import (
    CURVES_ALONE_FROM,
    DEFAULT_ALPHA,
    DEFAULT_COMBINED_ALPHA,
    DEFAULT_DESCRIPTOR_WEIGHT,
    DEFAULT_KERNEL_WEIGHT,
    DEFAULT_PRIOR_WEIGHT,
    DEFAULT_SAMPLES,
    EXACT_MAX_K,
    FULL_SIZE_ALPHA,
    FULL_SIZE_KERNEL_WEIGHT,
    KERNEL_POINTS,
    NON_ISOMETRIC_DISTORTION,
    NON_ISOMETRIC_SPECTRA,
    SIDE_CURVES,
    CombinedMapSolver,
    CurveMapSolver,
    FunctionalMaps,
    Hints,
    NO17Settings,
    balanced_weights,
    check_method_k,
    curves_alone_suffice,
    descriptor_functions,
    descriptor_least_squares,
    descriptor_part,
    no17_maps,
    normalised_eigenvalues,
)
from curvefm.progress import Progress, no_progress
from curvefm.registry import MethodPlugin
from curvefm.spectral import Basis, ShapePair, curve_function, normalised

NO17_DEFAULTS = NO17Settings()
NO_OPERATORS = np.zeros((0, 1, 1))


class CurvesParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    alpha: float = Field(DEFAULT_ALPHA, ge=0, description="weight of Laplacian commutativity")
    samples: int = Field(DEFAULT_SAMPLES, ge=2, le=10_000, description="uniform samples per curve")


class CombinedParams(CurvesParams):
    alpha: float = Field(DEFAULT_COMBINED_ALPHA, ge=0, description="weight of Laplacian commutativity")
    descriptor_weight: float = Field(
        DEFAULT_DESCRIPTOR_WEIGHT, ge=0, description="weight of wave kernel signature preservation"
    )
    kernel_weight: float = Field(
        DEFAULT_KERNEL_WEIGHT, ge=0, description="weight of the wave kernel maps at samples along the curves"
    )
    kernel_points: int = Field(
        KERNEL_POINTS, ge=2, le=100, description="curve samples with wave kernel maps, endpoints included"
    )
    prior_weight: float = Field(
        DEFAULT_PRIOR_WEIGHT,
        ge=0,
        description="weight of the landmark prior (NO17's map from the curves' endpoints) "
        "relative to the curve systems' mean diagonal, doubled with a single curve; 0: no prior, and the map always "
        "has the basis's size",
    )
    full_size_curves: int | None = Field(
        None,
        ge=1,
        le=100_000,
        description="with fewer curves than this (and a prior) the map has the prior's size, 50 x 50; unset (the "
        "default): until the curves' total length on the unit-area source reaches sqrt(k / pi), where they sample "
        "every frequency of the map. Below, its higher frequencies are not determined and would blur the pointwise map",
    )
    side_curves: int = Field(
        SIDE_CURVES,
        ge=0,
        le=100_000,
        description="up to this many curves the landmark prior also keeps each curve's side (left or right of the "
        "curve, which tells a shape from its mirror image); 0: never",
    )
    full_size_alpha: float = Field(
        FULL_SIZE_ALPHA, ge=0, description="weight of Laplacian commutativity once the whole map is handed out"
    )
    full_size_kernel_weight: float = Field(
        FULL_SIZE_KERNEL_WEIGHT, ge=0, description="weight of the wave kernel maps once the whole map is handed out"
    )
    non_isometric_distortion: float = Field(
        NON_ISOMETRIC_DISTORTION,
        ge=0,
        description=f"from {CURVES_ALONE_FROM} curves on, a pair whose curve "
        "endpoints' biharmonic distances differ by more than this (median |log ratio|, shapes scaled to unit area) "
        "is solved with the curve energy alone: the descriptors and the prior assume a near-isometry",
    )
    non_isometric_spectra: float = Field(
        NON_ISOMETRIC_SPECTRA,
        ge=0,
        description="once the whole map is handed out, a pair whose Laplace-Beltrami "
        "spectra differ by more than this (mean |log ratio| of the eigenvalues, shapes scaled to unit area) has its "
        "map's entries outside the prior's block damped: the curves determine those frequencies less well where the "
        "shapes are far from isometric",
    )

    def solver_params(self) -> dict[str, Any]:
        """The keyword arguments of :class:`CombinedMapSolver`: all but the rule :func:`run_combined` applies."""
        return self.model_dump(exclude={"non_isometric_distortion"})


def run_curves(pair: ShapePair, hints: Hints, params: CurvesParams, progress: Progress = no_progress) -> FunctionalMaps:
    return _solve_curves(CurveMapSolver, pair, hints, params.model_dump(), progress)


def run_combined(
    pair: ShapePair, hints: Hints, params: CombinedParams, progress: Progress = no_progress
) -> FunctionalMaps:
    if curves_alone_suffice(pair.basis_M, pair.basis_N, hints.curves, params.non_isometric_distortion):
        curve_energy = CurvesParams(alpha=params.alpha, samples=params.samples)  # the descriptors would mislead
        return _solve_curves(CurveMapSolver, pair, hints, curve_energy.model_dump(), progress)
    return _solve_curves(CombinedMapSolver, pair, hints, params.solver_params(), progress)


def _solve_curves(
    solver_class: type[CurveMapSolver], pair: ShapePair, hints: Hints, params: dict[str, Any], progress: Progress
) -> FunctionalMaps:
    if not hints.curves:
        raise InvalidInput("the curve-based methods need at least one pair of curves")
    k = min(pair.basis_M.k, pair.basis_N.k)
    vertices_and_bases = (pair.mesh_M.vertices, pair.basis_M, pair.mesh_N.vertices, pair.basis_N)
    if issubclass(solver_class, CombinedMapSolver):
        # the source's area for the size switch (full_size_length), the meshes for the sides of the curves in its prior
        params = {**params, "source_area": pair.mesh_M.area, "meshes": pair.meshes}
    with solver_class(*vertices_and_bases, k=k, **params) as solver:
        weights = hints.weights or (1.0,) * len(hints.curves)
        solver.add_curves([(pm, pn, w) for (pm, pn), w in zip(hints.curves, weights, strict=True)])
        progress(1.0, "maps solved")
        return FunctionalMaps(solver.C_MN, solver.C_NM)


class DescriptorParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    k: int = Field(NO17_DEFAULTS.k, ge=3, le=1000, description="size of the functional map")
    spectrum: int = Field(
        NO17_DEFAULTS.spectrum, ge=3, le=1000, description="eigenpairs used to build the wave kernels"
    )
    energies: int = Field(NO17_DEFAULTS.energies, ge=1, le=500, description="log-energies per wave kernel descriptor")
    sigma: float = Field(
        NO17_DEFAULTS.sigma, gt=0, description="filter width as a fraction of the log-eigenvalue range"
    )
    margin: float = Field(
        NO17_DEFAULTS.margin,
        ge=0,
        description="the energies start and end this many filter widths inside the log-eigenvalue range",
    )
    mu: float = Field(
        1.0,
        ge=0,
        description="weight of Laplacian commutativity relative to descriptor preservation (each "
        "term divided by its typical size)",
    )
    landmarks: bool = Field(
        True, description="add wave kernel maps at the landmarks; false: wave kernel signatures alone"
    )


class NO17Params(DescriptorParams):
    mu: float = Field(
        NO17_DEFAULTS.mu,
        ge=0,
        description="weight of Laplacian commutativity relative to descriptor preservation "
        "(each term divided by its typical size)",
    )
    inputs: Literal["landmarks", "curves"] = Field(
        "landmarks",
        description="'landmarks': wave kernels at the landmarks; 'curves': each curve as a function "
        "(-1 off the curve, normalised arc length on it), the paper's baseline test",
    )
    w_comm: float = Field(
        NO17_DEFAULTS.w_comm,
        ge=0,
        description="weight of descriptor commutativity relative to descriptor preservation (each term divided by "
        "its typical size)",
    )
    max_iter: int = Field(
        NO17_DEFAULTS.max_iter,
        ge=1,
        le=100_000,
        description=f"L-BFGS iterations (only for k > {EXACT_MAX_K}; smaller maps are exact)",
    )


def landmark_descriptors(pair: ShapePair, hints: Hints, params: DescriptorParams) -> tuple[np.ndarray, np.ndarray]:
    """Corresponding descriptor columns on M and N: WKS, and the wave kernel maps at the landmarks."""
    if params.landmarks and len(hints.landmarks) == 0:
        raise InvalidInput("the descriptor methods need at least one landmark (or one curve), or landmarks=false")
    landmarks = hints.landmarks if params.landmarks else np.zeros((0, 2), dtype=np.int64)
    settings = _settings(params)
    return (
        descriptor_functions(_spectrum(pair.basis_M, params.spectrum), landmarks[:, 0], settings),
        descriptor_functions(_spectrum(pair.basis_N, params.spectrum), landmarks[:, 1], settings),
    )


def _settings(params: DescriptorParams) -> NO17Settings:
    fields = ("k", "spectrum", "energies", "sigma", "margin", "mu", "w_comm", "max_iter")
    return NO17Settings(**{name: getattr(params, name) for name in fields if hasattr(params, name)})


def curve_descriptors(pair: ShapePair, hints: Hints) -> tuple[np.ndarray, np.ndarray]:
    if not hints.curves:
        raise InvalidInput("NO17 with inputs='curves' needs at least one pair of curves")
    F_M = np.column_stack([curve_function(pair.mesh_M.vertices, pm) for pm, _ in hints.curves])
    F_N = np.column_stack([curve_function(pair.mesh_N.vertices, pn) for _, pn in hints.curves])
    return normalised(pair.basis_M, F_M), normalised(pair.basis_N, F_N)


def _spectrum(basis: Basis, size: int) -> Basis:
    if size > basis.k:
        raise InvalidInput(f"spectrum = {size} eigenpairs asked for, but the basis has only {basis.k}")
    return basis.truncated(size)


def _coefficients(basis: Basis, functions: np.ndarray, k: int) -> np.ndarray:
    return basis.truncated(k).project(functions)


def run_obcs12(
    pair: ShapePair, hints: Hints, params: DescriptorParams, progress: Progress = no_progress
) -> FunctionalMaps:
    k = check_method_k(params.k, pair.basis_M, pair.basis_N)
    f_M, f_N = landmark_descriptors(pair, hints, params)
    A, B = _coefficients(pair.basis_M, f_M, k), _coefficients(pair.basis_N, f_N, k)
    lam_M, lam_N = normalised_eigenvalues(pair.basis_M, pair.basis_N, k)
    maps = []
    for F_from, F_to, l_from, l_to in ((A, B, lam_M, lam_N), (B, A, lam_N, lam_M)):
        w_descr, mu, _ = balanced_weights(F_from, F_to, l_from, l_to, NO_OPERATORS, NO_OPERATORS, params.mu, 0.0)
        maps.append(descriptor_least_squares(F_from, F_to, l_from, l_to, mu * F_from.shape[1] / w_descr))
    progress(1.0, "descriptor least squares solved")
    return FunctionalMaps(maps[0], maps[1])


def run_no17(pair: ShapePair, hints: Hints, params: NO17Params, progress: Progress = no_progress) -> FunctionalMaps:
    k = check_method_k(params.k, pair.basis_M, pair.basis_N)
    curves = params.inputs == "curves"
    f_M, f_N = curve_descriptors(pair, hints) if curves else landmark_descriptors(pair, hints, params)
    progress(0.0, "descriptor preservation and commutativity")
    part_M, part_N = descriptor_part(pair.basis_M, f_M, k), descriptor_part(pair.basis_N, f_N, k)
    maps = no17_maps(part_M, part_N, pair.basis_M, pair.basis_N, _settings(params))
    progress(1.0, "done")
    return maps


COMBINED = MethodPlugin(
    name="combined",
    description="Curve constraints plus wave kernel signatures and wave kernel maps along the curves, Laplacian "
    "commutativity: exact per-column solve (the default)",
    Params=CombinedParams,
    run=run_combined,
)
CURVES = MethodPlugin(
    name="curves",
    description="Curve-constrained functional maps (Gehre et al. 2018): exact per-column solve",
    Params=CurvesParams,
    run=run_curves,
)
OBCS12 = MethodPlugin(
    name="obcs12",
    description="Descriptor preservation (WKS + wave kernel maps at landmarks) and Laplacian commutativity, "
    "least squares (Ovsjanikov et al. 2012)",
    Params=DescriptorParams,
    run=run_obcs12,
)
NO17 = MethodPlugin(
    name="no17",
    description="OBCS12 plus descriptor commutativity, L-BFGS (Nogneng and Ovsjanikov 2017); inputs='curves' "
    "gives it the curves as functions",
    Params=NO17Params,
    run=run_no17,
)
