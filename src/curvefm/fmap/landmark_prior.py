"""NO17's map from landmarks (Nogneng and Ovsjanikov 2017, in pyFM 1.3's setup): the ``no17`` baseline and the
prior of the combined energy.

Descriptors: wave kernel signatures and the wave kernel maps at each landmark, from the first ``spectrum``
eigenpairs, each of unit L2 norm; the map (``k`` x ``k``, smaller than the curve maps: descriptor energies
degrade in large bases) minimises descriptor preservation, Laplacian commutativity and descriptor commutativity
with each term divided by its typical size (:func:`curvefm.fmap.balanced_weights`), exactly up to
:data:`curvefm.fmap.EXACT_MAX_K` and by L-BFGS above.

The descriptors split into parts that do not change while a person edits: the signatures of a shape, and the
kernels at one landmark. Each part's coefficients and multiplication operators are computed once and cached
by the basis's content, a landmark's from the eigenfunctions' operators (see ``_part``), so adding a curve costs
its two new landmarks' parts (10 ms each) and the solve (0.2-0.4 s per direction at k = 50, through a LAPACK
call that leaves the interpreter to other threads).

The combined energy computes these maps in the background while a person clicks on (its landmark prior): a
``wanted`` callback, asked before each descriptor part and each direction's solve, lets it give up as soon as
newer landmarks are wanted, so the cores go back to the clicks.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial
from typing import Any

import numpy as np

from curvefm.cache import LRU
from curvefm.fmap.baselines import (
    EXACT_MAX_K,
    DescriptorEnergy,
    balanced_weights,
    descriptor_least_squares,
    lbfgs,
    normalised_eigenvalues,
)
from curvefm.fmap.maps import FunctionalMaps
from curvefm.fmap.solver import basis_digest
from curvefm.spectral import (
    Basis,
    Quadrature,
    multiplication_operators,
    normalised,
    wave_kernel_map_coefficients,
    wave_kernel_maps,
    wave_kernel_signature,
)


@dataclass(frozen=True)
class NO17Settings:
    """pyFM's setup; ``mu`` and ``w_comm`` were chosen on FAUST 000 -> 011 and cat -> lion (docs/accuracy.md, "Baselines
    against pyFM")."""

    k: int = 50
    spectrum: int = 120
    energies: int = 20
    sigma: float = 0.07
    margin: float = 2.0
    mu: float = 0.01
    w_comm: float = 1.0
    max_iter: int = 300

    def filters(self) -> dict[str, Any]:
        return {"n_energies": self.energies, "sigma": self.sigma, "margin": self.margin}


@dataclass(frozen=True)
class DescriptorPart:
    """Some descriptors of one shape: their coefficients (k x d) and multiplication operators (d x k x k)."""

    coefficients: np.ndarray
    operators: np.ndarray


class NoLongerWanted(Exception):
    """Raised by :func:`landmark_maps` when its ``wanted`` callback says the maps are no longer needed."""


_PARTS: LRU[DescriptorPart] = LRU(256)  # at k = 50 a landmark's part is 0.4 MB: at most about 100 MB
_EIGEN_PRODUCTS: LRU[tuple[np.ndarray, np.ndarray]] = LRU(8)  # per basis, 2.5 MB at k = 50 (see _part)


def descriptor_functions(basis: Basis, landmarks: np.ndarray, settings: NO17Settings) -> np.ndarray:
    """The descriptors (n x d, unit norm each): wave kernel signatures, then the kernel maps at ``landmarks``."""
    spectral = basis.truncated(min(settings.spectrum, basis.k))
    columns = [wave_kernel_signature(spectral, **settings.filters())]
    if len(landmarks):
        columns.append(wave_kernel_maps(spectral, landmarks, **settings.filters()))
    return normalised(basis, np.hstack(columns))


def descriptor_part(
    basis: Basis, functions: np.ndarray, k: int, quadrature: Quadrature | None = None
) -> DescriptorPart:
    operators = multiplication_operators(basis, functions, k, quadrature)
    return DescriptorPart(basis.truncated(k).project(functions), operators)


def no17_maps(
    part_M: DescriptorPart,
    part_N: DescriptorPart,
    basis_M: Basis,
    basis_N: Basis,
    settings: NO17Settings,
    wanted: Callable[[], bool] = lambda: True,
) -> FunctionalMaps:
    """Both directions of NO17's map between corresponding descriptors."""
    k = settings.k
    lam_M, lam_N = normalised_eigenvalues(basis_M, basis_N, k)
    A, B, X, Y = part_M.coefficients, part_N.coefficients, part_M.operators, part_N.operators
    maps = []
    for F_from, F_to, l_from, l_to, X_from, X_to in ((A, B, lam_M, lam_N, X, Y), (B, A, lam_N, lam_M, Y, X)):
        _check(wanted)
        w_descr, mu, w_comm = balanced_weights(F_from, F_to, l_from, l_to, X_from, X_to, settings.mu, settings.w_comm)
        energy = DescriptorEnergy(F_from, F_to, l_from, l_to, X_from, X_to, mu, w_descr, w_comm)
        maps.append(energy.minimiser() if k <= EXACT_MAX_K else _quasi_newton(energy, settings.max_iter))
    return FunctionalMaps(maps[0], maps[1])


def landmark_maps(
    basis_M: Basis,
    basis_N: Basis,
    landmarks: np.ndarray,
    settings: NO17Settings = NO17Settings(),
    wanted: Callable[[], bool] = lambda: True,
    extra: tuple[np.ndarray, np.ndarray] | None = None,
    quadratures: tuple[Quadrature | None, Quadrature | None] = (None, None),
) -> FunctionalMaps:
    """NO17's maps from corresponding ``landmarks`` (m x 2 internal vertex ids), with cached descriptor parts.

    ``extra``: more corresponding descriptors (vertices x d on M and on N, such as the sides of a curve,
    :func:`curvefm.geometry.curve_side`), added with unit norm each (not cached).
    ``quadratures``: where given, each shape's multiplication operators are integrated on its samples
    (:func:`curvefm.spectral.scan_quadrature`).
    Raises :class:`NoLongerWanted` as soon as ``wanted()`` turns false (parts computed until then stay cached).
    """
    k = min(settings.k, basis_M.k, basis_N.k)
    settings = replace(settings, k=k)
    bases = (basis_M, basis_N)
    sides = [
        _descriptors(basis, landmarks[:, side], settings, wanted, quadratures[side]) for side, basis in enumerate(bases)
    ]
    if extra is not None:
        _check(wanted)
        added = [
            descriptor_part(basis, normalised(basis, f), k, quadrature)
            for basis, f, quadrature in zip(bases, extra, quadratures, strict=True)
        ]
        sides = [_joined(part, more) for part, more in zip(sides, added, strict=True)]
    return no17_maps(sides[0], sides[1], basis_M, basis_N, settings, wanted)


def _joined(*parts: DescriptorPart) -> DescriptorPart:
    return DescriptorPart(np.hstack([p.coefficients for p in parts]), np.concatenate([p.operators for p in parts]))


def _check(wanted: Callable[[], bool]) -> None:
    if not wanted():
        raise NoLongerWanted


def _descriptors(
    basis: Basis,
    landmarks: np.ndarray,
    settings: NO17Settings,
    wanted: Callable[[], bool],
    quadrature: Quadrature | None,
) -> DescriptorPart:
    """The signatures' part and each landmark's, from the cache where there."""
    digest = basis_digest(basis)
    parts = []
    for key in [None] + [int(vertex) for vertex in landmarks]:
        _check(wanted)
        cache_key = (digest, key, settings, quadrature is not None)
        parts.append(_PARTS.get(cache_key, partial(_part, basis, key, settings, quadrature)))
    return _joined(*parts)


def _part(
    basis: Basis, landmark: int | None, settings: NO17Settings, quadrature: Quadrature | None = None
) -> DescriptorPart:
    """The signatures (``landmark`` None) or the kernel maps at one landmark, of unit norm each.

    A landmark's kernel maps lie in the span of the first ``spectrum`` eigenfunctions, with coefficients ``c``,
    so their operators are ``sum_l c_l T_l`` for the eigenfunctions' operators ``T_l`` (made once per basis) and
    their coefficients and norms follow from the eigenfunctions' Gram matrix: no pass over the vertices per
    landmark (at 28k vertices a part cost 0.16 s of a core that way, and costs 10 ms this way; the operators agree
    to 1e-15)."""
    spectrum = min(settings.spectrum, basis.k)
    if landmark is None:
        functions = normalised(basis, wave_kernel_signature(basis.truncated(spectrum), **settings.filters()))
        return descriptor_part(basis, functions, settings.k, quadrature)
    leading = Basis(basis.evals[:spectrum], basis.evecs[:, :spectrum], basis.mass)  # a view: one row is read
    coefficients = wave_kernel_map_coefficients(leading, np.array([landmark]), **settings.filters())
    operators, gram = _EIGEN_PRODUCTS.get(
        (basis_digest(basis), spectrum, settings.k, quadrature is not None),
        lambda: _eigen_products(basis.truncated(spectrum), settings.k, quadrature),
    )
    coefficients = coefficients / np.sqrt(np.maximum(np.sum(coefficients * (gram @ coefficients), axis=0), 1e-300))
    return DescriptorPart(gram[: settings.k] @ coefficients, np.tensordot(coefficients, operators, axes=(0, 0)))


def _eigen_products(spectral: Basis, k: int, quadrature: Quadrature | None) -> tuple[np.ndarray, np.ndarray]:
    """The multiplication operators of ``spectral``'s eigenfunctions on the first ``k`` (spectral.k x k x k) and
    the eigenfunctions' Gram matrix under the mass (the identity up to the eigensolver's accuracy)."""
    operators = multiplication_operators(spectral, spectral.evecs, k, quadrature)
    return operators, spectral.project(spectral.evecs)


def _quasi_newton(energy: DescriptorEnergy, max_iter: int) -> np.ndarray:
    """L-BFGS from the map of descriptor preservation and Laplacian commutativity alone."""
    scale = energy.F_from.shape[1] / energy.w_descr
    start = descriptor_least_squares(energy.F_from, energy.F_to, energy.lam_from, energy.lam_to, energy.mu * scale)
    return lbfgs(energy, start, max_iter)[0]
