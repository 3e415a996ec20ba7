"""The combined energy: curve constraints, descriptors, landmark kernels and a landmark prior in one exact solve.

``C_MN`` minimises, with the curve solver's normalisations (:mod:`curvefm.fmap.solver`),

    alpha ||C Lam_M - Lam_N C||^2
    + sum_l w~_l (1/s) ||PsiBar_l C - PhiBar_l||^2                         curves (the paper)
    + w_d (1/d) ||S_N^T C - S_M^T||^2                                        wave kernel signatures
    + w_k sum_l w~_l (1/d_l) ||K_N,l^T C - K_M,l^T||^2                       wave kernel maps along the curves

``S_M`` (k x d) are the coefficients of the wave kernel signatures of M (unit L2 norm each), ``K_M,l`` (k x d_l)
those of the wave kernel maps at ``KERNEL_POINTS`` samples of curve l, evenly spaced from its start to its end
(so its endpoints are landmarks): the wave kernel map at a point p with energy e has the coefficients
``g_e(lam) * phi(p)``, the basis restricted to p filtered by the energy's band, so a curve's kernels come from
the restriction ``PhiBar_l`` the curve term computes anyway. Corresponding samples on the two curves give
corresponding functions.

Why descriptors enter as ``||F_N^T C - F_M^T||`` (the adjoint ``C^T`` carries N's descriptors to M's) rather than
OBCS12's ``||C F_M - F_N||``: the two agree for the near-orthogonal maps of near-isometries, and the adjoint form
has exactly the shape of a curve term (the curve term is the same statement for the band-limited deltas at the
curve samples). So the whole energy still separates by columns: column j of C solves
``(G + alpha diag((lam^N_i - lam^M_j)^2)) c_j = B[:, j]`` with the descriptors' and kernels' k x k products added
to G and B, an edit re-sums k x k matrices, and the update stays exact and as fast as the pure curve energy
(:mod:`curvefm.fmap.column_solve`). OBCS12's form turns the normal equations into ``G C + C H + D o C = R``, which
has no direct solver; preconditioned conjugate gradients on it needed 20-400 iterations (0.1-1 s) at k = 120 in
our trials and was no more accurate (docs/concepts.md, "The combined energy").

The landmark prior. With few curves the curve terms mislead: curves traced between corresponding endpoints do not
correspond point by point at equal arc length (a median 0.03-0.06 sqrt(area) off with 2 curves), while NO17 given
only the endpoints (descriptor commutativity on a 50 x 50 map, :mod:`curvefm.fmap.landmark_prior`) was 1.1-8x
more accurate up to 5 curves. Added as one more term inside the energy it cannot be column-separated, and its
solve costs 0.3-1.5 s. So it enters as a prior: ``w_p ||C[:50, :50] - C_NO17||^2``, with ``w_p`` relative to
the systems' mean diagonal. That adds ``w_p`` to the first 50 diagonal entries of the first 50 column systems and
``w_p C_NO17`` to their right-hand sides: the solve keeps its form and its speed, and the prior is computed once
per set of endpoints (in the background for an interactive solver). Until the curves are long enough to sample
the map's every frequency (:func:`full_size_length`; ``FULL_SIZE_CURVES`` curves where the source's area is not
known) the map is handed out at the prior's size: its higher frequencies are not determined by so few curves, and
converted to points they only blurred the map (FAUST, 2 curves: 0.043 at 120 x 120, 0.031 at 50 x 50). The prior's
settings come from experiments/combined_prior.py (docs/decisions.md#the-landmark-prior). From then on, the whole
map is solved with its own weights, ``FULL_SIZE_ALPHA`` and ``FULL_SIZE_KERNEL_WEIGHT`` (less commutativity, more
kernels: the curves now determine the higher frequencies; experiments/full_size_weights.py). The solver keeps the
curve and kernel terms' sums apart, so the weights change with the number of curves at no cost.

Left and right. Every descriptor above is intrinsic and cannot tell a shape from its mirror image; with one curve
from a person's head to a foot the prior mapped one arm onto the other. Up to ``SIDE_CURVES`` curves the prior also
preserves each curve's side (:func:`curvefm.geometry.curve_side`, whose sign the orientation sets) as one more
descriptor, where the sides agree under its map (``SIDE_AGREEMENT``); it is computed with the prior, never in an
edit (docs/accuracy.md#one-curve-that-cannot-flip).

Strongly non-isometric pairs. Wave kernel signatures, kernel maps and NO17 assume a near-isometry; where the shapes
are far from one (TOSCA's horse -> cat) they pull the map away from what the curves say, and from
``CURVES_ALONE_FROM`` curves on the pure curve energy is the better map. The only measure of isometry a user's input
gives is the curves' endpoints: :func:`landmark_distortion` compares their biharmonic distances on both shapes (from
the bases, so it costs microseconds per edit), and above ``NON_ISOMETRIC_DISTORTION`` the combined energy gives way
to the curve energy alone (:func:`curves_alone_suffice`, applied by the ``combined`` method and by a session's
solver; experiments/isometry_rule.py). Once the combined map is handed out whole,
where the two shapes' spectra differ by more than ``NON_ISOMETRIC_SPECTRA`` (:func:`spectral_mismatch`: isometric
shapes are isospectral) its frequencies beyond the prior's block are scaled by ``HIGH_FREQUENCY_DAMPING``
(experiments/high_frequency_damping.py).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, Future, wait
from dataclasses import dataclass
from functools import cached_property
from typing import Any, TypeVar, cast

import numpy as np

from curvefm.cache import LRU
from curvefm.errors import CurvefmError
from curvefm.fmap.column_solve import Prior
from curvefm.fmap.landmark_prior import NO17Settings, NoLongerWanted, landmark_maps
from curvefm.fmap.maps import EffectiveSolve, FunctionalMaps, curve_endpoints
from curvefm.fmap.solver import CurveMapSolver, CurveTerm, basis_digest, cross_products
from curvefm.geometry import Mesh, curve_side
from curvefm.spectral import Basis, Quadrature, energy_filters, normalised, scan_quadrature, wave_kernel_signature

# Chosen in docs/decisions.md#the-combined-energys-weights (the sweep in experiments/combined_weights.py):
# 7% above the sweep's best mean (kernel weight 1000), which was 1.5-4x worse than the curve energy with one curve
# on cat -> lion in `curvefm reproduce`'s random curves; alpha stays the curve energy's.
DEFAULT_COMBINED_ALPHA = 100.0
DEFAULT_DESCRIPTOR_WEIGHT = 100.0
DEFAULT_KERNEL_WEIGHT = 100.0
KERNEL_POINTS = 2
# chosen in docs/decisions.md#the-landmark-prior
DEFAULT_PRIOR_WEIGHT = 30.0
"""Weight of the landmark prior, relative to the mean diagonal of the curve systems: chosen by
experiments/combined_prior.py (docs/decisions.md#the-landmark-prior)."""
# chosen in docs/decisions.md#the-landmark-prior
ONE_CURVE_PRIOR_FACTOR = 2.0
"""With a single curve the prior's weight is multiplied by this: one curve's interior misleads most. On `curvefm
reproduce`'s suite it took FAUST-5k with one curve from 0.0463 to 0.0458 and TOSCA across classes from 0.129 to
0.125 (NO17: 0.0459, 0.1252); from 2 curves on the doubled weight was no better
(docs/decisions.md#the-landmark-prior)."""
# chosen in docs/decisions.md#map-sizes
FULL_SIZE_CURVES = 20
"""Where the source's area is not known (a solver built without ``source_area``), the map is handed out at the
prior's size (50 x 50) below this many curves: its higher frequencies are not determined by so few curves and only
blur the pointwise map (docs/decisions.md#map-sizes). With the area, :func:`full_size_length` decides instead."""


def full_size_length(k: int) -> float:
    """The curves' total length, on the unit-area source, from which the whole k x k map is handed out: ``sqrt(k /
    pi)``. Curves of that length spread evenly over the shape lie one wavelength of the k-th eigenfunction apart
    (Weyl's law on a unit-area surface: ``lam_k ~ 4 pi k``, wavelength ``2 pi / sqrt(lam_k)``), so they sample every
    frequency of the map. Adding curves one at a time in the UI's order (benchmarks/bench_monotone.py,
    experiments/monotone_rule.py) it took FAUST at k = 120 to the whole map at 7-8 curves instead of 20, with fewer
    clicks that made the map worse on the suite and on held-out pairs (docs/decisions.md#map-sizes)."""
    return float(np.sqrt(k / np.pi))


# chosen in docs/decisions.md#full-size-weights
FULL_SIZE_ALPHA = 30.0
FULL_SIZE_KERNEL_WEIGHT = 300.0
"""From ``FULL_SIZE_CURVES`` curves on, the map is solved with these instead of ``alpha`` and ``kernel_weight``: the
whole map is handed out, and its higher frequencies, which the weights above were swept for at the prior's size,
are determined by the curves. Chosen by a sweep at 20 curves on `curvefm reproduce`'s suite
(docs/decisions.md#full-size-weights): mean error 0.0100 / 0.0153 / 0.0114 / 0.0208 / 0.0469 -> 0.0088 / 0.0143 /
0.0108 / 0.0199 / 0.0464 on FAUST / FAUST-5k / TOSCA / cat -> lion / TOSCA across classes; within 4% of the
sweep's best on every dataset, as only 30 / 1000 also was."""
PRIOR_DELAY_S = 1.0
"""A live session's prior is computed once it has had no new curve for this long: in the browser benchmark, priors
computed beside back-to-back clicks took click-to-texture p95 at 28k vertices from 79 to 146-164 ms (computed after
every click) and from 89 to 130 ms (after 0.5 s without a new curve)."""
# chosen in docs/decisions.md#falling-back-to-the-curve-energy-on-non-isometric-pairs
NON_ISOMETRIC_DISTORTION = 0.25
"""A pair whose :func:`landmark_distortion` exceeds this counts as strongly non-isometric. Chosen by
experiments/isometry_rule.py on `curvefm reproduce`'s suite: with 10 curves TOSCA's horse -> cat measured
0.28-0.50 and david -> gorilla 0.24-0.35, the pairs the descriptors help at most 0.24 (wolf -> dog 0.22-0.24, FAUST
and FAUST-5k 0.02-0.24 with 5 to 20 curves, cat -> lion 0.10-0.15, cat0 -> cat2 0.07-0.09); the pairs across classes
outside the suite measure 0.06-0.43."""
# chosen in docs/decisions.md#falling-back-to-the-curve-energy-on-non-isometric-pairs
CURVES_ALONE_FROM = 5
"""From this many curves a strongly non-isometric pair is solved with the curve energy alone. With fewer, the curves
do not determine the map (with 2 curves the curve energy's error across TOSCA classes is twice NO17's). Measured
at held-out landmarks (experiments/isometry_rule.py,
docs/decisions.md#falling-back-to-the-curve-energy-on-non-isometric-pairs): across TOSCA classes with 5 / 10 / 20 curves
0.080 / 0.074 / 0.073 without the rule, 0.063 / 0.047 / 0.047 with it (the curve energy alone: 0.073 / 0.055 / 0.055);
on five pairs across classes outside the suite 0.066 / 0.050 / 0.049 -> 0.063 / 0.052 / 0.045."""
# chosen in docs/decisions.md#damping-high-frequencies
NON_ISOMETRIC_SPECTRA = 0.05
"""From ``FULL_SIZE_CURVES`` curves on, a pair whose :func:`spectral_mismatch` exceeds this has its map's high
frequencies damped. experiments/high_frequency_damping.py: on the reproduce suite FAUST and TOSCA within classes
measure 0.009-0.042, cat -> lion and TOSCA across classes 0.056-0.092; on twelve pairs outside the suite, FAUST and
TOSCA within classes 0.010-0.039, across classes cat -> dog, horse -> wolf and michael -> gorilla 0.053-0.069, but
dog -> horse 0.041 and victoria -> david 0.021 (damping would have helped those too). The endpoints' landmark
distortion separates less well: FAUST's pairs measure up to 0.22, cat -> lion 0.12-0.14 and wolf -> dog 0.21-0.23."""
# chosen in docs/decisions.md#damping-high-frequencies
HIGH_FREQUENCY_DAMPING = 0.25
"""From ``FULL_SIZE_CURVES`` curves on, a pair above ``NON_ISOMETRIC_SPECTRA`` has its map handed out whole but with
every entry outside the prior's 50 x 50 block multiplied by this: the curves determine those frequencies less well
where the descriptors and the prior mislead. experiments/high_frequency_damping.py with 20 curves and the
full-size weights, mean error of the runs above the threshold (across TOSCA classes at held-out landmarks): on the
suite 0.0643 -> 0.0609 (0.5: 0.0599; cut off at 50 x 50: 0.0652), on the pairs outside it 0.0894 -> 0.0625 (0.5:
0.0709); on the seven runs it still governs once strongly non-isometric pairs fall back to the curve energy
(cat -> lion, wolf -> dog, one of cat -> dog) 0.0493 -> 0.0324 (block alone 0.0396); FAUST and TOSCA within classes
lose with any damping (FAUST 0.0088 -> 0.0103 at 0.25)."""
# chosen in docs/accuracy.md#one-curve-that-cannot-flip
SIDE_CURVES = 2
"""Up to this many curves the landmark prior also preserves each curve's side (:func:`curvefm.geometry.curve_side`):
with one curve from the head to a foot on FAUST 000 -> 011 the prior from its two endpoints mapped one arm onto
the other (0.26 of sqrt(area)); the curve's side took it to 0.03 (experiments/curve_side.py, three endpoint draws
on three suite and four held-out pairs: mean 0.062 -> 0.036). With two curves the sides took the mean from 0.0368
to 0.0361 (cat -> lion 0.049 -> 0.046; one run of 21 worse, by 1%); from 10 curves on they are left out."""
# chosen in docs/accuracy.md#one-curve-that-cannot-flip
SIDE_AGREEMENT = 0.5
"""The prior with the curves' sides is kept only where they agree under it (:func:`sides_agree`): where a curve runs
round a limb on one shape and the other way round on the other, its sides disagree under any map (FAUST-5k 000 ->
011, two of three endpoint draws: correlation -0.2 and -0.35 under the sided prior; 0.85-0.95 where they agree), and
the prior from the endpoints alone is used."""
SIDE_ROWS = 500  # target vertices at which the sides are compared
T = TypeVar("T")
Landmarks = frozenset[tuple[int, ...]]  # the curves' endpoint pairs (vertex on M, vertex on N)


@dataclass(frozen=True)
class PriorInputs:
    """What a landmark prior is computed from: the curves' endpoints and the paths of the curves whose sides it
    preserves (``(path_M, path_N)`` as int32 bytes; none with more than the solver's ``side_curves`` curves)."""

    landmarks: Landmarks
    sided: tuple[tuple[bytes, bytes], ...] = ()

    def paths(self) -> list[tuple[np.ndarray, np.ndarray]]:
        return [(np.frombuffer(path_M, np.int32), np.frombuffer(path_N, np.int32)) for path_M, path_N in self.sided]


SUPERSEDED = object()  # what a prior job returns when newer endpoints were asked for while it waited
ENERGIES = 20
SIGMA = 0.06

log = logging.getLogger(__name__)
_SIGNATURES: LRU[np.ndarray] = LRU(16)  # by basis content: every session on a shape shares them


def signature_products(basis_M: Basis, basis_N: Basis) -> np.ndarray:
    """``[S_M S_M^T, S_N S_N^T, S_N S_M^T] / d`` (3 x k x k) for the wave kernel signatures of both shapes."""
    S_M, S_N = signature_coefficients(basis_M), signature_coefficients(basis_N)
    return np.stack([S_M @ S_M.T, S_N @ S_N.T, S_N @ S_M.T]) / S_M.shape[1]


def signature_coefficients(basis: Basis) -> np.ndarray:
    """Coefficients (k x ENERGIES) of the unit-norm wave kernel signatures of a basis; computed once per basis
    (cached by the basis's content, so every session on the same shape shares them)."""
    key = (basis_digest(basis), ENERGIES, SIGMA)
    return _SIGNATURES.get(key, lambda: basis.project(normalised(basis, wave_kernel_signature(basis, ENERGIES, SIGMA))))


def kernel_filters(evals: np.ndarray) -> np.ndarray:
    """The wave kernels' filters (ENERGIES x k - 1, the constant function skipped) for a basis's eigenvalues
    (unit-area mesh, not normalised: the filters are on log-eigenvalues)."""
    return energy_filters(evals, ENERGIES, SIGMA)


def kernel_coefficients(restricted: np.ndarray, filters: np.ndarray, points: int = KERNEL_POINTS) -> np.ndarray:
    """Unit-norm coefficients (k x points * ENERGIES) of the wave kernel maps at ``points`` samples of a curve.

    ``restricted`` (s x k) is the basis at the curve's s samples (a curve term's ``PhiBar``), ``filters`` the
    basis's :func:`kernel_filters`.
    """
    s, k = restricted.shape
    rows = np.unique(np.linspace(0, s - 1, points).round().astype(int))
    kernels: np.ndarray = np.zeros((len(rows), ENERGIES, k))
    kernels[:, :, 1:] = restricted[rows, None, 1:] * filters[None]
    kernels = kernels.reshape(-1, k)
    kernels /= np.maximum(np.linalg.norm(kernels, axis=1, keepdims=True), 1e-300)
    return kernels.T


def landmark_distortion(basis_M: Basis, basis_N: Basis, landmarks: np.ndarray) -> float:
    """How far from an isometry corresponding landmarks say the pair is: the median over pairs of landmarks
    ``(a, b)`` of ``|log(d_N(a', b') / d_M(a, b))|``, with ``d`` the biharmonic distance of each basis (Lipman,
    Rustamov, Funkhouser 2010; the bases are of the shapes scaled to unit area). ``landmarks``: ``(vertex on M,
    vertex on N)`` rows. 0 for fewer than two."""
    pairs = np.triu_indices(len(landmarks), 1)
    d_M, d_N = (biharmonic_distances(basis, landmarks[:, side])[pairs] for side, basis in enumerate((basis_M, basis_N)))
    apart = (d_M > 0) & (d_N > 0)  # two landmarks may share a vertex on one shape
    ratios = np.log(d_N[apart] / d_M[apart])
    return float(np.median(np.abs(ratios))) if len(ratios) else 0.0


def spectral_mismatch(basis_M: Basis, basis_N: Basis) -> float:
    """How far from an isometry the pair's Laplace-Beltrami spectra say it is, with no landmarks: the mean over
    the non-constant eigenpairs both bases hold of ``|log(lam_i^N / lam_i^M)|`` (isometric shapes are
    isospectral; the bases are of the shapes scaled to unit area)."""
    k = min(basis_M.k, basis_N.k)
    lam_M, lam_N = basis_M.evals[1:k], basis_N.evals[1:k]
    positive = (lam_M > 0) & (lam_N > 0)
    return float(np.mean(np.abs(np.log(lam_N[positive] / lam_M[positive])))) if positive.any() else 0.0


def biharmonic_distances(basis: Basis, vertices: np.ndarray) -> np.ndarray:
    """Biharmonic distances between ``vertices``: ``sqrt(sum_i (phi_i(a) - phi_i(b))^2 / lam_i^2)`` over the basis
    without its constant function."""
    embedded = basis.evecs[vertices, 1:] / basis.evals[1:]
    squared = np.sum(embedded**2, axis=1)
    return np.sqrt(np.maximum(squared[:, None] + squared[None, :] - 2 * embedded @ embedded.T, 0.0))


def curves_alone_suffice(
    basis_M: Basis,
    basis_N: Basis,
    curves: Sequence[tuple[np.ndarray, np.ndarray]],
    threshold: float = NON_ISOMETRIC_DISTORTION,
) -> bool:
    """Whether the combined energy should give way to the curve energy for these ``(path_M, path_N)`` curves: from
    ``CURVES_ALONE_FROM`` of them on, on a pair their endpoints show strongly non-isometric."""
    if len(curves) < CURVES_ALONE_FROM:
        return False
    return curves_distortion(basis_M, basis_N, curves) > threshold


def curves_distortion(basis_M: Basis, basis_N: Basis, curves: Sequence[tuple[np.ndarray, np.ndarray]]) -> float:
    """The :func:`landmark_distortion` of the ``(path_M, path_N)`` curves' endpoints."""
    return landmark_distortion(basis_M, basis_N, curve_endpoints(curves))


class CombinedMapSolver(CurveMapSolver):
    """:class:`CurveMapSolver` on the combined energy (module doc): same editing, ids, ``sync`` and threads.

    A curve is still stored as its two vertex paths; its k x k products (curve and kernel terms together) are
    computed from one restriction of the bases when it is added and again when it is removed or replaced.
    The signatures' products are fixed for the pair and added to the curves' sums at each solve.

    The landmark prior: NO17's map from the curves' endpoints (:func:`curvefm.fmap.landmark_maps`), which the
    leading block of C is pulled towards with ``prior_weight``. It costs 0.3-1.5 s at FAUST's size, so an
    ``interactive`` solver given a ``prior_executor`` computes it there (after ``PRIOR_DELAY_S`` without a new
    curve), one job at a time, when its maps are read; until it lands the maps are solved with the last prior
    whose landmarks are all still there (or none), and :attr:`prior_pending` says so. Without an executor it is
    computed in the solve. Given both ``meshes``, up to ``side_curves`` curves the prior also preserves each
    curve's side (``SIDE_CURVES``), which tells a shape from its mirror image.
    """

    PRODUCTS = 6  # the curve term's three products, then the kernel term's (unweighted)

    def __init__(
        self,
        *args: Any,
        alpha: float = DEFAULT_COMBINED_ALPHA,
        descriptor_weight: float = DEFAULT_DESCRIPTOR_WEIGHT,
        kernel_weight: float = DEFAULT_KERNEL_WEIGHT,
        kernel_points: int = KERNEL_POINTS,
        prior_weight: float = DEFAULT_PRIOR_WEIGHT,
        full_size_curves: int | None = None,
        source_area: float | None = None,
        full_size_alpha: float = FULL_SIZE_ALPHA,
        full_size_kernel_weight: float = FULL_SIZE_KERNEL_WEIGHT,
        non_isometric_spectra: float = NON_ISOMETRIC_SPECTRA,
        prior_executor: Executor | None = None,
        meshes: tuple[Mesh, Mesh] | None = None,
        side_curves: int = SIDE_CURVES,
        **kwargs: Any,
    ) -> None:
        super().__init__(*args, alpha=alpha, **kwargs)  # type: ignore[misc]  # args: the shapes and bases, k
        self.descriptor_weight, self.kernel_weight = float(descriptor_weight), float(kernel_weight)
        self.kernel_points, self.prior_weight = kernel_points, float(prior_weight)
        self.full_size_curves, self.source_area = full_size_curves, source_area
        self.full_size_alpha, self.full_size_kernel_weight = float(full_size_alpha), float(full_size_kernel_weight)
        self.damps_high_frequencies = spectral_mismatch(self.basis_M, self.basis_N) > non_isometric_spectra
        self._signatures = self.descriptor_weight * signature_products(self.basis_M, self.basis_N)
        self._filters_M, self._filters_N = kernel_filters(self.basis_M.evals), kernel_filters(self.basis_N.evals)
        self._prior_executor, self.meshes = prior_executor, meshes
        self.side_curves = side_curves if meshes is not None else 0
        self._prior: tuple[PriorInputs, FunctionalMaps | None] | None = None  # (its inputs, NO17's maps, if any)
        self._prior_job: tuple[PriorInputs, Future[FunctionalMaps | object]] | None = None
        self._wanted = PriorInputs(frozenset())  # the inputs whose prior was last asked for
        self._lengths: dict[str, tuple[CurveTerm, float]] = {}  # curve id -> (its term, its path's length on M)
        self.on_prior: Callable[[], None] | None = None
        """Called (on the prior's thread) when a prior computed in the background lands: the maps will change."""

    def _side_factor(self, side: str, path: np.ndarray) -> np.ndarray:
        """The curve's factor on one side with its kernels' rows below, ``[PhiBar / sqrt(s); K_M^T / sqrt(d)]``
        (and the same on N), restricted once for both terms."""
        restricted = self._restricted(side, path)
        kernels = kernel_coefficients(
            restricted, self._filters_M if side == "M" else self._filters_N, self.kernel_points
        )
        return np.vstack([restricted * (1.0 / np.sqrt(self.samples)), kernels.T * (1.0 / np.sqrt(kernels.shape[1]))])

    def _factor_params(self) -> tuple[Any, ...]:
        return (self.kernel_points, ENERGIES, SIGMA)

    def _products(self, term: CurveTerm) -> np.ndarray:
        """The curve term's and the kernel term's products apart, so that the kernel weight is applied when the
        sums are read and may change with the number of curves."""
        X, Y = self._factors(term)
        s = self.samples
        return np.concatenate([cross_products(X[:s], Y[:s]), cross_products(X[s:], Y[s:])])

    @property
    def length_rule(self) -> bool:
        """Whether the curves' length decides the map's size (:func:`full_size_length`): with the source's area and
        no ``full_size_curves`` count asked for (without the area, ``FULL_SIZE_CURVES`` curves decide)."""
        return self.full_size_curves is None and self.source_area is not None

    @property
    def curves_length(self) -> float:
        """The curves' total length on M scaled to unit area (0 without ``source_area``)."""
        if self.source_area is None:
            return 0.0
        if len(self._lengths) > 2 * len(self.curves):
            self._lengths = {curve_id: self._lengths[curve_id] for curve_id in self.curves if curve_id in self._lengths}
        return sum(self._path_length(curve_id, term) for curve_id, term in self.curves.items()) / float(
            np.sqrt(self.source_area)
        )

    def _path_length(self, curve_id: str, term: CurveTerm) -> float:
        """A curve's path length on M, computed once per term: every edit asks :attr:`full_size` a dozen times."""
        known = self._lengths.get(curve_id)
        if known is None or known[0] is not term:
            known = (term, float(np.linalg.norm(np.diff(self.vertices_M[term.path_M], axis=0), axis=1).sum()))
            self._lengths[curve_id] = known
        return known[1]

    @property
    def full_size(self) -> bool:
        """Whether the curves determine the whole map and its weights: their length reaches
        :func:`full_size_length` (:attr:`length_rule`), or there are ``full_size_curves`` (default
        ``FULL_SIZE_CURVES``) of them."""
        if self.length_rule:
            return self.curves_length >= full_size_length(self.k)
        return len(self.curves) >= (self.full_size_curves or FULL_SIZE_CURVES)

    @property
    def commutativity_weight(self) -> float:
        return self.full_size_alpha if self.full_size else self.alpha

    @property
    def kernel_weight_now(self) -> float:
        """The kernel weight the maps are solved with now."""
        return self.full_size_kernel_weight if self.full_size else self.kernel_weight

    def _weighted(self, mean_products: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        G_M, G_N, B = mean_products[:3] + self.kernel_weight_now * mean_products[3:] + self._signatures
        return G_M, G_N, B

    def _solve(self) -> None:
        if self._prior_job is not None:  # a running job for other endpoints gives up now, not at the next read
            self._wanted = self._prior_inputs()
        super()._solve()

    # -- the landmark prior -----------------------------------------------------------------------------
    @property
    def C_MN(self) -> np.ndarray:
        self._adopt_finished_prior()  # a prior that landed since the last read makes the maps stale
        return super().C_MN

    @property
    def C_NM(self) -> np.ndarray:
        self._adopt_finished_prior()
        return super().C_NM

    @property
    def prior_pending(self) -> bool:
        """Whether the maps will change once the prior for the current curves' endpoints lands."""
        return self.prior_weight > 0 and bool(self.curves) and not self._prior_matches(self._prior_inputs())

    def settle(self) -> None:
        """Bring the prior up to date with the curves now, waiting for (or computing) it: for the final maps."""
        landmarks = self._prior_inputs()
        if self.prior_weight <= 0 or not self.curves or self._prior_matches(landmarks):
            return
        if self._prior_job is not None:
            wait([self._prior_job[1]])
        if not self._prior_matches(landmarks):
            self._compute_prior(landmarks)
        self._stale = {"MN", "NM"}

    def _prior_inputs(self) -> PriorInputs:
        paths = [(t.path_M, t.path_N) for t in self.curves.values()]
        sided = tuple((M.tobytes(), N.tobytes()) for M, N in paths) if len(paths) <= self.side_curves else ()
        return PriorInputs(frozenset(map(tuple, curve_endpoints(paths).tolist())), sided)

    def _prior_matches(self, landmarks: PriorInputs) -> bool:
        self._adopt_finished_prior()
        return self._prior is not None and self._prior[0] == landmarks

    def _adopt_finished_prior(self) -> None:
        if self._prior_job is None or not self._prior_job[1].done():
            return
        landmarks, job = self._prior_job
        self._prior_job = None
        maps = _or_none(job.result)
        current = self._prior_inputs()
        if self._prior is not None and self._prior[0] == current:
            return
        if maps is SUPERSEDED:  # the maps were solved without it already: no read would ask for the current one
            if self.curves:
                self._start_prior(current)
            return
        self._prior = (landmarks, cast("FunctionalMaps | None", maps))  # a prior job returns these or SUPERSEDED
        self._stale = {"MN", "NM"} if self.curves else self._stale

    def _priors(self) -> tuple[Prior | None, Prior | None]:
        if self.prior_weight <= 0 or not self.curves:
            return None, None
        landmarks = self._prior_inputs()
        if not self._prior_matches(landmarks):
            self._start_prior(landmarks)
        if self._prior is None or self._prior[1] is None or not self._prior[0].landmarks <= landmarks.landmarks:
            return None, None
        G_M, G_N, _ = self.normal_equations()
        weight = self.prior_weight * (ONE_CURVE_PRIOR_FACTOR if len(self.curves) == 1 else 1.0)
        weight *= float(np.trace(G_M) + np.trace(G_N)) / (2 * self.k)  # relative to the mean diagonal
        maps = self._prior[1]
        return Prior(maps.C_MN, weight), Prior(maps.C_NM, weight)

    def _compute_prior(self, landmarks: PriorInputs) -> None:
        self._prior = (landmarks, _or_none(lambda: self._landmark_maps(landmarks)))

    def _landmark_maps(self, inputs: PriorInputs, wanted: Callable[[], bool] = lambda: True) -> FunctionalMaps:
        """NO17's maps from the endpoints, with the sided curves' sides where these agree under the map."""
        pairs, sides = _pairs(inputs.landmarks), self._curve_sides(inputs)
        bases, quadratures = (self.basis_M, self.basis_N), self._quadratures
        if sides is not None:
            maps = landmark_maps(*bases, pairs, wanted=wanted, extra=sides, quadratures=quadratures)
            if sides_agree(maps.C_MN, self.basis_M, self.basis_N, sides):
                return maps
        return landmark_maps(*bases, pairs, wanted=wanted, quadratures=quadratures)

    @cached_property
    def _quadratures(self) -> tuple[Quadrature | None, Quadrature | None]:
        """Scans' samples for the prior's multiplication operators (:func:`curvefm.spectral.scan_quadrature`)."""
        return (
            scan_quadrature(self.vertices_M, self.basis_M.mass),
            scan_quadrature(self.vertices_N, self.basis_N.mass),
        )

    def _curve_sides(self, inputs: PriorInputs) -> tuple[np.ndarray, np.ndarray] | None:
        """Each sided curve's :func:`curve_side` on both shapes (vertices x curves), or None."""
        if self.meshes is None or not inputs.sided:
            return None
        mesh_M, mesh_N = self.meshes
        paths = inputs.paths()
        return (
            np.column_stack([curve_side(mesh_M, path_M) for path_M, _ in paths]),
            np.column_stack([curve_side(mesh_N, path_N) for _, path_N in paths]),
        )

    def _start_prior(self, landmarks: PriorInputs) -> None:
        if self._prior_executor is None or not self.interactive:
            self._compute_prior(landmarks)
        else:
            if self._prior_job is not None and self._prior_job[1].cancel():  # outdated before it started
                self._prior_job = None
            self._wanted = landmarks
            if self._prior_job is None:  # else it runs: the next read after it lands asks for the current one
                job = self._prior_executor.submit(self._quiet_prior, landmarks)
                self._prior_job = (landmarks, job)
                job.add_done_callback(self._landed)

    def _landed(self, job: Future[FunctionalMaps | object]) -> None:
        if (
            self.on_prior is not None
            and not job.cancelled()
            and job.exception() is None
            and job.result() is not SUPERSEDED
        ):
            self.on_prior()

    def _quiet_prior(self, landmarks: PriorInputs) -> FunctionalMaps | object:
        """The prior, once the session has been left alone for ``PRIOR_DELAY_S``: while a person clicks on, each
        job finds newer endpoints wanted and returns :data:`SUPERSEDED`, at once or, if the click came while it
        ran, at its next step (a few tenths of a second), so the clicks keep the cores."""
        time.sleep(PRIOR_DELAY_S)
        try:
            return self._landmark_maps(landmarks, wanted=lambda: self._wanted == landmarks)
        except NoLongerWanted:
            return SUPERSEDED

    # -- the maps handed out -----------------------------------------------------------------------------
    @property
    def prior_size(self) -> int:
        """The landmark prior's block: the leading ``min(50, k)`` frequencies."""
        return min(NO17Settings().k, self.k)

    @property
    def map_size(self) -> int:
        """The size the maps are handed out at: the prior's block until the curves determine the whole map
        (:attr:`full_size`), then k."""
        return self.prior_size if self.prior_weight > 0 and not self.full_size else self.k

    @property
    def damped(self) -> bool:
        """Whether the frequencies beyond the prior's block are scaled by ``HIGH_FREQUENCY_DAMPING`` now."""
        return self.prior_weight > 0 and self.full_size and self.damps_high_frequencies

    def _sized(self, C: np.ndarray) -> np.ndarray:
        size = self.prior_size
        if self.map_size < self.k:
            return C[:size, :size].copy()
        if not self.damped:
            return C
        damped = C * HIGH_FREQUENCY_DAMPING
        damped[:size, :size] = C[:size, :size]
        return damped

    def effective(self) -> EffectiveSolve:
        """The combined energy's weights as applied now (``prior`` relative to the systems' mean diagonal,
        ``high_frequency_damping`` where applied) and the size handed out, with why."""
        weights = {"alpha": self.commutativity_weight, "descriptors": self.descriptor_weight}
        weights["kernels"] = self.kernel_weight_now
        if self.prior_weight > 0:
            weights["prior"] = self.prior_weight * (ONE_CURVE_PRIOR_FACTOR if len(self.curves) == 1 else 1.0)
        if self.damped:
            weights["high_frequency_damping"] = HIGH_FREQUENCY_DAMPING
        summary, reason = self._full_size_reason() if self.full_size else self._prior_size_reason()
        return EffectiveSolve("combined", weights, self.map_size, summary, reason)

    def _switch(self) -> tuple[str, str]:
        """What hands out the whole map, in a few words, and where the curves stand now."""
        if self.length_rule:
            length = f"{full_size_length(self.k):.1f} sqrt(area)"
            return f"curves totalling {length}", f"{self.curves_length:.1f} now"
        return f"{self.full_size_curves or FULL_SIZE_CURVES} curves", f"{len(self.curves)} now"

    def _prior_size_reason(self) -> tuple[str, str]:
        k, size = self.k, self.map_size
        energy = f"the combined energy with alpha {self.alpha:g} and kernels {self.kernel_weight:g}"
        if self.prior_weight <= 0:
            return f"combined; {k} x {k}", f"{energy}, without a landmark prior (the shapes are too big for it)"
        if size == k:
            return f"combined; {k} x {k}", f"{energy}; k = {k} is within the landmark prior's {self.prior_size}"
        until, now = self._switch()
        return (
            f"combined; {size} x {size} until {until}",
            f"{energy}; below {until} ({now}) the map is handed out at the landmark prior's {size} x {size}, not the "
            f"k = {k} asked: so few curves do not determine its higher frequencies, which only blurred the "
            "pointwise map",
        )

    def _full_size_reason(self) -> tuple[str, str]:
        k, alpha = self.k, self.full_size_alpha
        until, now = self._switch()
        summary = f"combined; {k} x {k} from {until}, alpha {alpha:g}"
        reason = (
            f"the combined energy; from {until} ({now}) the whole k = {k} map, solved with "
            f"the full-size weights alpha {alpha:g} and kernels {self.full_size_kernel_weight:g} instead of "
            f"alpha {self.alpha:g} and kernels {self.kernel_weight:g}"
        )
        if not self.damped:
            return summary, reason
        block, factor = self.prior_size, HIGH_FREQUENCY_DAMPING
        return (
            f"{summary}, high frequencies x {factor:g}",
            f"{reason}; the shapes' spectra differ (not near-isometric), so its frequencies beyond the first "
            f"{block} are scaled by {factor:g}",
        )


def sides_agree(C_MN: np.ndarray, basis_M: Basis, basis_N: Basis, sides: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether every curve's side on N correlates with its side on M carried by ``C_MN``'s pointwise map (nearest
    neighbours in the spectral embedding, at ``SIDE_ROWS`` vertices of N) by at least ``SIDE_AGREEMENT``."""
    k_N, k_M = C_MN.shape
    rows = np.unique(np.linspace(0, basis_N.n_vertices - 1, SIDE_ROWS).astype(np.int64))
    embedded = basis_M.evecs[:, :k_M] @ C_MN.T
    queries = basis_N.evecs[rows, :k_N]
    nearest = np.argmin(np.sum(embedded**2, axis=1)[None, :] - 2 * queries @ embedded.T, axis=1)
    side_M, side_N = sides
    for carried, wanted in zip(side_M[nearest].T, side_N[rows].T, strict=True):
        if np.std(carried) == 0 or np.std(wanted) == 0 or np.corrcoef(carried, wanted)[0, 1] < SIDE_AGREEMENT:
            return False
    return True


def _pairs(landmarks: Landmarks) -> np.ndarray:
    return np.array(sorted(landmarks), dtype=np.int64).reshape(-1, 2)


def _or_none(compute: Callable[[], T]) -> T | None:
    """The prior, or None (the maps are then solved without one) if NO17's energy has no unique minimiser."""
    try:
        return compute()
    except CurvefmError as error:
        log.warning("no landmark prior: %s", error)
        return None
