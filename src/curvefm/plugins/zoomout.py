"""Converter plugin ``zoomout``: spectral upsampling (Melzi, Ren, Rodola, Sharma, Wonka, Ovsjanikov,
"ZoomOut: Spectral Upsampling for Efficient Shape Correspondence", SIGGRAPH Asia 2019).

Starting from the ``nearest-neighbor`` maps, for k = k_init, k_init + step, ..., k_final: fit the k x k
functional map of each pointwise map, then convert it back to a pointwise map by nearest neighbours in k
dimensions. The ends of the user's curves stay pinned (:class:`~curvefm.pointwise.CurvePins`): after every
conversion each end maps to the same end of its partner curve. The curves' inner vertices are evidence, not pins:
each fit blends their images with their arc-length partners by ``curve_interior_weight``. With ``samples`` set,
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
from curvefm.plugins.refinement_params import SampledRefinementParams, curve_interior_weight_field
from curvefm.plugins.refiner import Curves, Iterate, SpectralRefiner, Start
from curvefm.pointwise import CurvePins, PointwiseMaps, VertexRows, fit_fmap, no_pins
from curvefm.progress import Progress, no_progress, scaled
from curvefm.spectral import Basis, ShapePair

# chosen in docs/decisions.md#curve-pins
CURVE_INTERIOR_WEIGHT = 0.25
"""ZoomOut's default ``curve_interior_weight``: its fits blend the curves' inner vertices' images with their arc-length
partners by this much (ICP and RHM's ZoomOut start use none)."""


class ZoomOutParams(SampledRefinementParams):
    curve_interior_weight: float = curve_interior_weight_field(CURVE_INTERIOR_WEIGHT)
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
    def _sizes_agree(self) -> ZoomOutParams:
        if self.k_final < self.k_init:
            raise ValueError(f"k_final ({self.k_final}) must be at least k_init ({self.k_init})")
        if self.samples is not None and self.samples < self.k_final:
            raise ValueError(f"samples ({self.samples}) must be at least k_final ({self.k_final})")
        return self


# chosen in docs/decisions.md#the-refinement-guard
STAGE_STRIDE = 10
"""Every this many basis functions below ``k_final`` ZoomOut offers its maps, stopped there, as an earlier stage for
the guard (:func:`curvefm.matching.convert`) to fall back to when the whole refinement makes an intrinsic figure
worse (docs/decisions.md#the-refinement-guard)."""


class ZoomOut(SpectralRefiner[ZoomOutParams]):
    """ZoomOut as a :class:`~curvefm.plugins.refiner.SpectralRefiner`: step k fits ``k x k`` maps, k growing from
    ``k_init`` by ``step`` to ``k_final``; on samples the fit at ``k_final`` converts every vertex. It keeps
    earlier stages for the guard (:data:`STAGE_STRIDE`)."""

    name = "zoomout"
    description = "ZoomOut spectral upsampling (Melzi et al. 2019) from k_init to k_final, optionally on samples"
    Params = ZoomOutParams

    def basis_size(self, params: ZoomOutParams) -> int:
        """The last map's basis size: a pair whose bases are smaller makes ZoomOut compute larger ones itself."""
        return params.k_final

    def schedule(self, state: Iterate, params: ZoomOutParams) -> list[int]:
        """k_init, k_init + step, ..., k_final; on samples without k_final, which :meth:`finish` fits to convert
        every vertex."""
        sizes = list(range(params.k_init, params.k_final, params.step)) + [params.k_final]
        return sizes[:-1] if state.sampled else sizes

    def fit(
        self, p2p: np.ndarray, domain: VertexRows, image: VertexRows, step: int, params: ZoomOutParams
    ) -> np.ndarray:
        return fit_fmap(p2p, domain, image, step)

    def final_step(self, params: ZoomOutParams) -> int:
        return params.k_final

    def both_embeddings(self, params: ZoomOutParams) -> bool:
        return params.embedding == "both"

    def step_message(self, step: int, params: ZoomOutParams) -> str:
        return f"ZoomOut k = {step} (up to {params.k_final})"

    def end_message(self, state: Iterate, steps_run: int, params: ZoomOutParams) -> str:
        return f"ZoomOut finished at k = {params.k_final}"

    def step(self, state: Iterate, step: int, params: ZoomOutParams) -> bool:
        """One size; every :data:`STAGE_STRIDE`-th size below ``k_final`` is kept as an earlier stage."""
        super().step(state, step, params)
        if step < params.k_final and (params.k_final - step) % STAGE_STRIDE == 0:
            assert state.fitted is not None, "the step has just fitted them"
            state.earlier.append((step, state.fitted if state.sampled else state.maps))
        return False

    def refine_stages(
        self, start: Start, params: ZoomOutParams, progress: Progress = no_progress
    ) -> Iterator[tuple[str, PointwiseMaps]]:
        """``("k = k_final", maps)``, then, each only when asked for, the maps stopped at every ``STAGE_STRIDE``-th
        size below, largest first. Iterating on every vertex, an earlier stage is the maps that iteration produced;
        on samples, it costs one conversion of every vertex with the maps fitted at that size, as the last
        iteration does."""
        state = self.iterate(self.begin(start), params, progress)
        yield f"k = {params.k_final}", self.finish(state, params)
        for k, stage in reversed(state.earlier):
            yield f"k = {k}", stage if isinstance(stage, PointwiseMaps) else self.every_vertex(state, stage, params)

    def stages(
        self,
        pair: ShapePair,
        fmaps: FunctionalMaps,
        params: ZoomOutParams,
        progress: Progress = no_progress,
        curves: Curves = (),
    ) -> Iterator[tuple[str, PointwiseMaps]]:
        """:meth:`refine_stages` from the ``nearest-neighbor`` maps of ``fmaps``, with the user's curves pinned."""
        start = self.start(pair, fmaps, params, scaled(progress, 0.0, 0.1), curves)
        yield from self.refine_stages(start, params, scaled(progress, 0.1, 1.0))

    def refine(self, start: Start, params: ZoomOutParams, progress: Progress = no_progress) -> PointwiseMaps:
        """ZoomOut's maps at ``k_final`` (the first of :meth:`refine_stages`)."""
        return next(self.refine_stages(start, params, progress))[1]


REFINER = ZoomOut()


def zoomout_stages(
    maps: PointwiseMaps,
    basis_M: Basis,
    basis_N: Basis,
    params: ZoomOutParams,
    samples: tuple[np.ndarray, np.ndarray] | None = None,
    progress: Progress = no_progress,
    pins: CurvePins | None = None,
) -> Iterator[tuple[str, PointwiseMaps]]:
    """ZoomOut from pointwise maps (:meth:`ZoomOut.refine_stages`). ``samples`` is ``(ids_M, ids_N)`` for the fast
    variant, else None; ``maps`` hold one entry per sample then (:func:`~curvefm.pointwise.initial_maps` with the
    samples), else per vertex. ``pins`` fix the partners of the curves' vertices after every conversion."""
    pins = pins or no_pins(basis_M.n_vertices, basis_N.n_vertices)
    yield from REFINER.refine_stages(Start(maps, pins, samples, (basis_M, basis_N)), params, progress)


def convert_zoomout(
    pair: ShapePair,
    fmaps: FunctionalMaps,
    params: ZoomOutParams,
    progress: Progress = no_progress,
    curves: Curves = (),
) -> PointwiseMaps:
    """ZoomOut's maps at ``k_final`` (:meth:`ZoomOut.convert`)."""
    return REFINER.convert(pair, fmaps, params, progress, curves)


def zoomout_basis_size(params: ZoomOutParams) -> int:
    """The last map's basis size (:meth:`ZoomOut.basis_size`)."""
    return REFINER.basis_size(params)


ZOOMOUT = REFINER.plugin()
