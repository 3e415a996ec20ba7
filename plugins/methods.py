"""Method plugins ``combined`` (the default), ``curves``, ``obcs12`` and ``no17``: functional maps from curves
or landmarks.

See :mod:`curvefm.fmap.combined` and :mod:`curvefm.fmap.baselines` for the energies. The descriptor baselines
follow pyFM 1.3's setup:
wave kernel signatures and wave kernel maps at the landmarks from the first ``spectrum`` eigenpairs, a map
of size ``k`` (smaller than ours: descriptor methods degrade in large bases, see docs/results.md), each term
divided by its typical size (:func:`curvefm.fmap.balanced_weights`). What made them as accurate as pyFM
(``benchmarks/bench_pyfm.py``; README, "Baselines against pyFM"): that normalisation, which lets redundant
descriptors count once, and energies kept two filter widths inside the spectrum; the exact solve (no17)
and using every descriptor's operator changed little.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from curvefm.errors import InvalidInput
from curvefm.fmap import (
    DEFAULT_ALPHA,
    DEFAULT_COMBINED_ALPHA,
    DEFAULT_DESCRIPTOR_WEIGHT,
    DEFAULT_KERNEL_WEIGHT,
    DEFAULT_SAMPLES,
    EXACT_MAX_K,
    KERNEL_POINTS,
    CombinedMapSolver,
    CurveMapSolver,
    DescriptorEnergy,
    FunctionalMaps,
    Hints,
    balanced_weights,
    check_method_k,
    descriptor_least_squares,
    lbfgs,
    normalised_eigenvalues,
)
from curvefm.progress import Progress, no_progress
from curvefm.registry import MethodPlugin
from curvefm.spectral import (
    Basis,
    ShapePair,
    curve_function,
    multiplication_operators,
    normalised,
    wave_kernel_maps,
    wave_kernel_signature,
)

W_COMM = 1.0  # chosen on FAUST 000 -> 011 and cat -> lion, see the README ("Baselines against pyFM")
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


def run_curves(
    pair: ShapePair, hints: Hints, params: CurvesParams, progress: Progress = no_progress
) -> FunctionalMaps:
    return _solve_curves(CurveMapSolver, pair, hints, params.model_dump(), progress)


def run_combined(
    pair: ShapePair, hints: Hints, params: CombinedParams, progress: Progress = no_progress
) -> FunctionalMaps:
    return _solve_curves(CombinedMapSolver, pair, hints, params.model_dump(), progress)


def _solve_curves(
    solver_class: type[CurveMapSolver], pair: ShapePair, hints: Hints, params: dict, progress: Progress
) -> FunctionalMaps:
    if not hints.curves:
        raise InvalidInput("the curve-based methods need at least one pair of curves")
    k = min(pair.basis_M.k, pair.basis_N.k)
    vertices_and_bases = (pair.mesh_M.vertices, pair.basis_M, pair.mesh_N.vertices, pair.basis_N)
    with solver_class(*vertices_and_bases, k=k, **params) as solver:
        weights = hints.weights or (1.0,) * len(hints.curves)
        solver.add_curves([(pm, pn, w) for (pm, pn), w in zip(hints.curves, weights, strict=True)])
        progress(1.0, "maps solved")
        return FunctionalMaps(solver.C_MN, solver.C_NM)


class DescriptorParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    k: int = Field(50, ge=3, le=1000, description="size of the functional map")
    spectrum: int = Field(120, ge=3, le=1000, description="eigenpairs used to build the wave kernels")
    energies: int = Field(20, ge=1, le=500, description="log-energies per wave kernel descriptor")
    sigma: float = Field(0.07, gt=0, description="filter width as a fraction of the log-eigenvalue range")
    margin: float = Field(
        2.0, ge=0, description="the energies start and end this many filter widths inside the log-eigenvalue range"
    )
    mu: float = Field(
        1.0, ge=0, description="weight of Laplacian commutativity relative to descriptor preservation (each "
        "term divided by its typical size)",
    )
    landmarks: bool = Field(
        True, description="add wave kernel maps at the landmarks; false: wave kernel signatures alone"
    )


class NO17Params(DescriptorParams):
    mu: float = Field(
        0.01, ge=0, description="weight of Laplacian commutativity relative to descriptor preservation (each "
        "term divided by its typical size)",
    )
    inputs: Literal["landmarks", "curves"] = Field(
        "landmarks",
        description="'landmarks': wave kernels at the landmarks; 'curves': each curve as a function "
        "(-1 off the curve, normalised arc length on it), the paper's baseline test",
    )
    w_comm: float = Field(
        W_COMM, ge=0, description="weight of descriptor commutativity relative to descriptor preservation (each "
        "term divided by its typical size)",
    )
    max_iter: int = Field(
        300, ge=1, le=100_000, description=f"L-BFGS iterations (only for k > {EXACT_MAX_K}; smaller maps are exact)"
    )


def landmark_descriptors(
    pair: ShapePair, hints: Hints, params: DescriptorParams
) -> tuple[np.ndarray, np.ndarray]:
    """Corresponding descriptor columns on M and N: WKS, and the wave kernel maps at the landmarks."""
    if params.landmarks and len(hints.landmarks) == 0:
        raise InvalidInput("the descriptor methods need at least one landmark (or one curve), or landmarks=false")
    out = []
    for side, basis in ((0, pair.basis_M), (1, pair.basis_N)):
        spectral = _spectrum(basis, params.spectrum)
        filters = {"n_energies": params.energies, "sigma": params.sigma, "margin": params.margin}
        columns = [wave_kernel_signature(spectral, **filters)]
        if params.landmarks:
            columns.append(wave_kernel_maps(spectral, hints.landmarks[:, side], **filters))
        out.append(normalised(basis, np.hstack(columns)))
    return out[0], out[1]


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
    A, B = _coefficients(pair.basis_M, f_M, k), _coefficients(pair.basis_N, f_N, k)
    X = multiplication_operators(pair.basis_M, f_M, k)
    Y = multiplication_operators(pair.basis_N, f_N, k)
    lam_M, lam_N = normalised_eigenvalues(pair.basis_M, pair.basis_N, k)
    maps = []
    for step, (F_from, F_to, l_from, l_to, X_from, X_to) in enumerate(
        ((A, B, lam_M, lam_N, X, Y), (B, A, lam_N, lam_M, Y, X))
    ):
        progress(0.5 * step, "descriptor preservation and commutativity")
        w_descr, mu, w_comm = balanced_weights(F_from, F_to, l_from, l_to, X_from, X_to, params.mu, params.w_comm)
        energy = DescriptorEnergy(F_from, F_to, l_from, l_to, X_from, X_to, mu, w_descr, w_comm)
        maps.append(energy.minimiser() if k <= EXACT_MAX_K else _quasi_newton(energy, params.max_iter))
    progress(1.0, "done")
    return FunctionalMaps(maps[0], maps[1])


def _quasi_newton(energy: DescriptorEnergy, max_iter: int) -> np.ndarray:
    """L-BFGS from the map of descriptor preservation and Laplacian commutativity alone."""
    scale = energy.F_from.shape[1] / energy.w_descr
    start = descriptor_least_squares(energy.F_from, energy.F_to, energy.lam_from, energy.lam_to, energy.mu * scale)
    return lbfgs(energy, start, max_iter)[0]


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
