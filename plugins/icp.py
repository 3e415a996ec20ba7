"""Converter plugin ``icp``: the orthogonal refinement of Ovsjanikov et al. 2012 ("Functional Maps", SIGGRAPH).

Starting from the ``nearest-neighbor`` maps, each iteration fits, for each direction, the functional map
closest to the current pointwise map among maps with orthonormal columns (an isometry preserves the
mass-orthonormality of the unit-area bases), then converts it back to a pointwise map by nearest neighbours,
in which the user's curves stay pinned (:class:`~curvefm.pointwise.CurvePins`). On big shapes (or with
``samples``) the iterations run on farthest-point samples and every vertex is matched once at the end
(:mod:`curvefm.pointwise.sampled`).

The map is rectangular: ``k`` functions on its domain, ``k_image > k`` on its image (as in pyFM's ICP).
Square maps drift here: on FAUST 000 -> 011 with 10 curves, square k = 50 went from 0.028 to 0.10 in fifteen
iterations (k = 80: 0.039 in ten), while 50 x 80 went to 0.021 (mean geodesic error / sqrt(area)). Presumably the
eigenfunctions near a common cut-off k have no partner below it on the other shape; the extra image functions
give them one.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field, model_validator

from curvefm.fmap import FunctionalMaps
from curvefm.plugins.refinement_params import SampledRefinementParams
from curvefm.pointwise import (
    CurvePins,
    PointwiseMaps,
    VertexRows,
    bases_with,
    fit_fmap,
    initial_maps,
    match_rows,
    no_pins,
    refinement_samples,
)
from curvefm.progress import Progress, no_progress, scaled
from curvefm.registry import ConverterPlugin
from curvefm.spectral import Basis, ShapePair


class IcpParams(SampledRefinementParams):
    k: int = Field(50, ge=2, le=1000, description="basis functions on the domain side of each map (its columns)")
    k_image: int = Field(
        80, ge=2, le=1000, description="basis functions on the image side of each map (its rows); at least k"
    )
    iterations: int = Field(
        15, ge=1, le=500, description="most ICP iterations; stops early when the maps stop changing"
    )

    @model_validator(mode="after")
    def _sizes_agree(self):
        if self.k_image < self.k:
            raise ValueError(f"k_image ({self.k_image}) must be at least k ({self.k})")
        if self.samples is not None and self.samples < self.k_image:
            raise ValueError(f"samples ({self.samples}) must be at least k_image ({self.k_image})")
        return self


def nearest_orthogonal(C: np.ndarray) -> np.ndarray:
    """The matrix with orthonormal columns closest to ``C`` in Frobenius norm (``U V^T`` of its SVD)."""
    U, _, Vt = np.linalg.svd(C, full_matrices=False)
    return U @ Vt


def orthogonal_fmap(p2p: np.ndarray, domain: VertexRows, image: VertexRows, params: IcpParams) -> np.ndarray:
    """The ``k_image x k`` map with orthonormal columns closest to the one fitted from ``p2p``. ``p2p`` maps the
    domain's rows to image vertices, so the functional map goes the other way: ``k`` functions of the image
    (its columns) to ``k_image`` of the domain (its rows)."""
    return nearest_orthogonal(fit_fmap(p2p, domain, image, params.k_image, params.k))


def icp(
    maps: PointwiseMaps,
    basis_M: Basis,
    basis_N: Basis,
    params: IcpParams,
    samples: tuple[np.ndarray, np.ndarray] | None = None,
    progress: Progress = no_progress,
    pins: CurvePins | None = None,
) -> PointwiseMaps:
    """ICP from pointwise maps, on every vertex or on ``samples`` ``(ids_M, ids_N)`` with one conversion of
    every vertex at the end (``maps`` then hold one entry per sample); ``pins`` fix the partners of the
    curves' vertices after every conversion."""
    ids_M, ids_N = samples if samples is not None else (None, None)
    rows_M, rows_N = VertexRows(basis_M, ids_M), VertexRows(basis_N, ids_N)
    pins = pins or no_pins(basis_M.n_vertices, basis_N.n_vertices)
    p_NM, p_MN = pins.pin_NM(maps.p2p_NM, rows_N.subset), pins.pin_MN(maps.p2p_MN, rows_M.subset)
    for it in range(params.iterations):
        progress(it / params.iterations, f"ICP iteration {it + 1} of at most {params.iterations}")
        C_MN, C_NM = orthogonal_fmap(p_NM, rows_N, rows_M, params), orthogonal_fmap(p_MN, rows_M, rows_N, params)
        new_NM = pins.pin_NM(match_rows(C_MN, rows_N, rows_M, params.search), rows_N.subset)
        new_MN = pins.pin_MN(match_rows(C_NM, rows_M, rows_N, params.search), rows_M.subset)
        converged = np.array_equal(new_NM, p_NM) and np.array_equal(new_MN, p_MN)
        p_NM, p_MN = new_NM, new_MN
        if converged:
            break
    progress(1.0, f"ICP stopped after {it + 1} iterations")
    if samples is None:
        return PointwiseMaps(p2p_NM=p_NM, p2p_MN=p_MN)
    C_MN, C_NM = orthogonal_fmap(p_NM, rows_N, rows_M, params), orthogonal_fmap(p_MN, rows_M, rows_N, params)
    every_M, every_N = VertexRows(basis_M), VertexRows(basis_N)
    return PointwiseMaps(
        p2p_NM=pins.pin_NM(match_rows(C_MN, every_N, every_M, params.search)),
        p2p_MN=pins.pin_MN(match_rows(C_NM, every_M, every_N, params.search)),
    )


def convert_icp(
    pair: ShapePair, fmaps: FunctionalMaps, params: IcpParams, progress: Progress = no_progress, curves=()
) -> PointwiseMaps:
    progress(0.0, "choosing the vertices to iterate on")
    samples = refinement_samples(pair.mesh_M, pair.mesh_N, params.samples, params.dense_up_to)
    progress(0.05, "initial maps (nearest neighbours)")
    maps = initial_maps(pair, fmaps, params.search, samples)
    basis_M, basis_N = bases_with(pair, params.k_image, scaled(progress, 0.05, 0.1))
    pins = CurvePins.from_curves(pair.mesh_M, pair.mesh_N, curves)
    return icp(maps, basis_M, basis_N, params, samples, scaled(progress, 0.1, 1.0), pins)


def icp_basis_size(params: IcpParams) -> int:
    """The image side's basis size: a pair whose bases are smaller makes ICP compute larger ones itself."""
    return params.k_image


ICP = ConverterPlugin(
    name="icp",
    description="Orthogonal ICP refinement of both maps (Ovsjanikov et al. 2012), from the nearest-neighbour maps",
    Params=IcpParams,
    run=convert_icp,
    basis_size=icp_basis_size,
    takes_curves=True,
)
