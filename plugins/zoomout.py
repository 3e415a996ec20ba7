"""Converter plugin ``zoomout``: spectral upsampling (Melzi, Ren, Rodola, Sharma, Wonka, Ovsjanikov,
"ZoomOut: Spectral Upsampling for Efficient Shape Correspondence", SIGGRAPH Asia 2019).

Starting from the ``nearest-neighbor`` maps, for k = k_init, k_init + step, ..., k_final: fit the k x k
functional map of each pointwise map, then convert it back to a pointwise map by nearest neighbours in k
dimensions. The user's curves stay pinned (:class:`~curvefm.pointwise.CurvePins`): after every conversion
the vertices of each curve map onto its partner curve, so each fitted map keeps them. With ``samples`` set,
or by default on shapes of more than ``dense_up_to`` vertices, the iterations run on farthest-point samples
of each shape (the paper's fast variant, :mod:`curvefm.pointwise.sampled`) and only the last conversion is at
full resolution.

Starting at the session's own k (usually 120) is much worse than starting low: curve constraints pin down
the low frequencies only. On FAUST 000 -> 011 with 10 curves, 120 -> 200 reached 0.025 (from 0.028), while
20 -> 120 reached 0.011 (mean geodesic error / sqrt(area); see benchmarks/bench_converters.py).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Literal

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


class ZoomOutParams(SampledRefinementParams):
    k_init: int = Field(20, ge=2, le=1000, description="basis size of the first functional map fitted")
    k_final: int = Field(
        120, ge=2, le=1000, description="basis size of the last map (a larger basis than the session's is computed)"
    )
    step: int = Field(5, ge=1, le=100, description="basis functions added per iteration")
    embedding: Literal["single", "both"] = Field(
        "single",
        description="'single': each pointwise map from its own functional map (the paper); 'both': from both "
        "maps at once, as the nearest-neighbor converter",
    )

    @model_validator(mode="after")
    def _sizes_agree(self):
        if self.k_final < self.k_init:
            raise ValueError(f"k_final ({self.k_final}) must be at least k_init ({self.k_init})")
        if self.samples is not None and self.samples < self.k_final:
            raise ValueError(f"samples ({self.samples}) must be at least k_final ({self.k_final})")
        return self


STAGE_STRIDE = 10
"""Every this many basis functions below ``k_final`` ZoomOut offers its maps, stopped there, as an earlier stage for
the guard (:func:`curvefm.matching.convert`) to fall back to when the whole refinement makes an intrinsic figure
worse (README, "Refinement keeps the user's curves and never returns a worse map")."""


def zoomout_stages(
    maps: PointwiseMaps,
    basis_M: Basis,
    basis_N: Basis,
    params: ZoomOutParams,
    samples: tuple[np.ndarray, np.ndarray] | None = None,
    progress: Progress = no_progress,
    pins: CurvePins | None = None,
) -> Iterator[tuple[str, PointwiseMaps]]:
    """ZoomOut from pointwise maps: ``("k = k_final", maps)``, then, each only when asked for, the maps stopped at
    every ``STAGE_STRIDE``-th size below, largest first. ``samples`` is ``(ids_M, ids_N)`` for the fast variant,
    else None; ``maps`` hold one entry per sample then (:func:`~curvefm.pointwise.initial_maps` with the samples),
    else per vertex. ``pins`` fix the partners of the curves' vertices after every conversion.

    Iterating on every vertex, an earlier stage is the maps that iteration produced; on samples, it costs one
    conversion of every vertex with the maps fitted at that size, as the last iteration does."""
    ids_M, ids_N = samples if samples is not None else (None, None)
    rows_M, rows_N = VertexRows(basis_M, ids_M), VertexRows(basis_N, ids_N)
    pins = pins or no_pins(basis_M.n_vertices, basis_N.n_vertices)
    p_NM, p_MN = pins.pin_NM(maps.p2p_NM, rows_N.subset), pins.pin_MN(maps.p2p_MN, rows_M.subset)
    sizes = list(range(params.k_init, params.k_final, params.step)) + [params.k_final]
    earlier = []  # (k, stage): the maps at k, or the fitted maps to convert every vertex with
    for i, k in enumerate(sizes):
        progress(i / len(sizes), f"ZoomOut k = {k} (up to {params.k_final})")
        C_MN, C_NM = fit_fmap(p_NM, rows_N, rows_M, k), fit_fmap(p_MN, rows_M, rows_N, k)
        last = i == len(sizes) - 1
        if last and samples is not None:
            rows_M, rows_N = VertexRows(basis_M), VertexRows(basis_N)
        p_NM, p_MN = _converted(C_MN, C_NM, rows_M, rows_N, params, pins)
        if not last and (params.k_final - k) % STAGE_STRIDE == 0:
            earlier.append((k, (C_MN, C_NM) if samples is not None else PointwiseMaps(p2p_NM=p_NM, p2p_MN=p_MN)))
    progress(1.0, f"ZoomOut finished at k = {params.k_final}")
    yield f"k = {params.k_final}", PointwiseMaps(p2p_NM=p_NM, p2p_MN=p_MN)
    every_M, every_N = VertexRows(basis_M), VertexRows(basis_N)
    for k, stage in reversed(earlier):
        if isinstance(stage, PointwiseMaps):
            yield f"k = {k}", stage
        else:
            p_NM, p_MN = _converted(*stage, every_M, every_N, params, pins)
            yield f"k = {k}", PointwiseMaps(p2p_NM=p_NM, p2p_MN=p_MN)


def _converted(C_MN, C_NM, rows_M: VertexRows, rows_N: VertexRows, params: ZoomOutParams, pins: CurvePins):
    """Both pointwise maps (on the rows given) from the fitted maps, with the curves pinned."""
    both = params.embedding == "both"
    p_NM = pins.pin_NM(match_rows(C_MN, rows_N, rows_M, params.search, C_NM if both else None), rows_N.subset)
    p_MN = pins.pin_MN(match_rows(C_NM, rows_M, rows_N, params.search, C_MN if both else None), rows_M.subset)
    return p_NM, p_MN


def convert_zoomout_stages(
    pair: ShapePair, fmaps: FunctionalMaps, params: ZoomOutParams, progress: Progress = no_progress, curves=()
) -> Iterator[tuple[str, PointwiseMaps]]:
    """:func:`zoomout_stages` from the ``nearest-neighbor`` maps of ``fmaps``, with the user's curves pinned."""
    progress(0.0, "choosing the vertices to iterate on")
    samples = refinement_samples(pair.mesh_M, pair.mesh_N, params.samples, params.dense_up_to)
    progress(0.05, "initial maps (nearest neighbours)")
    maps = initial_maps(pair, fmaps, params.search, samples)
    basis_M, basis_N = bases_with(pair, params.k_final, scaled(progress, 0.1, 0.2))
    pins = CurvePins.from_curves(pair.mesh_M, pair.mesh_N, curves)
    yield from zoomout_stages(maps, basis_M, basis_N, params, samples, scaled(progress, 0.25, 1.0), pins)


def convert_zoomout(
    pair: ShapePair, fmaps: FunctionalMaps, params: ZoomOutParams, progress: Progress = no_progress, curves=()
) -> PointwiseMaps:
    """ZoomOut's maps at ``k_final`` (the first of :func:`convert_zoomout_stages`)."""
    return next(convert_zoomout_stages(pair, fmaps, params, progress, curves))[1]


def zoomout_basis_size(params: ZoomOutParams) -> int:
    """The last map's basis size: a pair whose bases are smaller makes ZoomOut compute larger ones itself."""
    return params.k_final


ZOOMOUT = ConverterPlugin(
    name="zoomout",
    description="ZoomOut spectral upsampling (Melzi et al. 2019) from k_init to k_final, optionally on samples",
    Params=ZoomOutParams,
    run=convert_zoomout,
    basis_size=zoomout_basis_size,
    takes_curves=True,
    stages=convert_zoomout_stages,
)
