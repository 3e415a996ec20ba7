"""The iterative refiner that the refining converters (``icp``, ``zoomout``, ``rhm``) are built on.

Every refiner does the same three things, written once here:

1. **Start** (:meth:`IterativeRefiner.start`, a :class:`Start`; :meth:`SpectralRefiner.start` for ICP and
   ZoomOut): the vertices to iterate on (every vertex, or farthest-point samples on big shapes:
   :mod:`curvefm.pointwise.sampled`), the ``nearest-neighbor`` converter's maps on them
   (:func:`curvefm.pointwise.initial_maps`), bases with as many functions as the refiner works in, and the
   user's curves as pins (:class:`~curvefm.pointwise.CurvePins`).
2. **Iterate** (:meth:`IterativeRefiner.iterate`): one step after another from the refiner's schedule until the
   schedule ends or a step says the maps have settled, reporting progress per step.
3. **Convert**: each step ends in pointwise maps with the curves pinned again.

:class:`SpectralRefiner` is steps 2 and 3 for the refiners that alternate between functional and pointwise
maps (ICP, ZoomOut, after geomfum's ``IterativeRefiner``): fit both functional maps to the current pointwise
maps, convert them back by nearest neighbours, pin; on samples, one last fit converts every vertex. ICP and
ZoomOut differ only in how they fit (orthonormal ``k_image x k`` maps, or ``k x k`` maps growing by ``step``),
in their schedule and in when they stop; their parameters are
:class:`~curvefm.plugins.refinement_params.SampledRefinementParams`. RHM (:mod:`curvefm.plugins.rhm`) shares the
loop and starts from its own maps (ZoomOut's by default), with its own parameters; its step is an alternating
minimisation in a geodesic embedding rather than a fit.

Map directions follow :mod:`curvefm.pointwise.conversion`: ``p2p_NM[j]`` is the vertex of M for vertex j of N.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import numpy as np
from pydantic import BaseModel

from curvefm.fmap import FunctionalMaps
from curvefm.plugins.refinement_params import SampledRefinementParams
from curvefm.pointwise import (
    CurvePins,
    PointwiseMaps,
    VertexRows,
    bases_with,
    initial_maps,
    match_rows,
    refinement_samples,
)
from curvefm.progress import Progress, no_progress, scaled
from curvefm.registry import ConverterPlugin
from curvefm.spectral import Basis, ShapePair

P = TypeVar("P", bound=BaseModel)
"""A refiner's parameter model."""
SP = TypeVar("SP", bound=SampledRefinementParams)
"""A :class:`SpectralRefiner`'s parameter model: ``samples``, ``dense_up_to`` and ``search`` choose its start."""
State = TypeVar("State")
Curves = Sequence[tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class Start:
    """Where a refinement starts: ``maps`` (one entry per vertex, or per sample where ``samples`` is
    ``(ids_M, ids_N)``), the user's curves as ``pins``, and bases of M and N with enough functions (None for a
    refiner that needs none)."""

    maps: PointwiseMaps
    pins: CurvePins
    samples: tuple[np.ndarray, np.ndarray] | None = None
    bases: tuple[Basis, Basis] | None = None


class IterativeRefiner(ABC, Generic[P, State]):
    """A refining converter: a start from the ``nearest-neighbor`` maps with the curves pinned, then a loop of
    steps. A subclass gives its ``name``, ``description`` and ``Params``, its start, its schedule and its step;
    :meth:`plugin` makes the :class:`~curvefm.registry.ConverterPlugin` that the entry point names."""

    name: str
    description: str
    Params: type[P]

    # -- the start ---------------------------------------------------------------------------------------
    def basis_size(self, params: P) -> int:
        """The basis functions per shape the refiner works in: a pair whose bases are smaller makes the refiner
        compute larger ones itself (0: none needed)."""
        return 0

    @abstractmethod
    def start(
        self, pair: ShapePair, fmaps: FunctionalMaps, params: P, progress: Progress = no_progress, curves: Curves = ()
    ) -> Start:
        """Where the refinement starts: maps (on the vertices to iterate on), the curves' pins and the bases the
        refiner needs."""

    # -- the loop ----------------------------------------------------------------------------------------
    @abstractmethod
    def schedule(self, state: State, params: P) -> Sequence[Any]:
        """The steps from ``state``, in order; the loop ends after the last unless a step settles first."""

    @abstractmethod
    def step(self, state: State, step: Any, params: P) -> bool:
        """Advance ``state`` by one ``step`` (in place); True when the maps have settled and the loop may stop."""

    @abstractmethod
    def step_message(self, step: Any, params: P) -> str:
        """What progress says while ``step`` runs."""

    @abstractmethod
    def end_message(self, state: State, steps_run: int, params: P) -> str:
        """What progress says when the loop has ended after ``steps_run`` steps."""

    def iterate(self, state: State, params: P, progress: Progress = no_progress) -> State:
        """The refinement loop: each step of :meth:`schedule` in turn until one settles."""
        steps = self.schedule(state, params)
        steps_run = 0
        for i, step in enumerate(steps):
            progress(i / len(steps), self.step_message(step, params))
            steps_run = i + 1
            if self.step(state, step, params):
                break
        progress(1.0, self.end_message(state, steps_run, params))
        return state

    # -- the converter -----------------------------------------------------------------------------------
    def stages(
        self, pair: ShapePair, fmaps: FunctionalMaps, params: P, progress: Progress = no_progress, curves: Curves = ()
    ) -> Iterator[tuple[str, PointwiseMaps]]:
        """``(label, maps)``: the refined maps first, then earlier stages where the refiner has them (see
        :attr:`curvefm.registry.ConverterPlugin.stages`). By default the one stage :meth:`convert` returns."""
        yield "", self.convert(pair, fmaps, params, progress, curves)

    @abstractmethod
    def convert(
        self, pair: ShapePair, fmaps: FunctionalMaps, params: P, progress: Progress = no_progress, curves: Curves = ()
    ) -> PointwiseMaps:
        """Both pointwise maps, refined from the ``nearest-neighbor`` maps of ``fmaps`` with ``curves`` pinned."""

    def has_stages(self) -> bool:
        return type(self).stages is not IterativeRefiner.stages

    def plugin(self) -> ConverterPlugin[P]:
        return ConverterPlugin(
            name=self.name,
            description=self.description,
            Params=self.Params,
            run=self.convert,
            basis_size=self.basis_size,
            takes_curves=True,
            stages=self.stages if self.has_stages() else None,
        )


@dataclass
class Iterate:
    """The state of a :class:`SpectralRefiner`: the rows it iterates on, the pins, the current maps on those rows
    and the functional maps the last step fitted (``C_MN``: coefficients on M to N, fitted from ``p_NM``)."""

    rows_M: VertexRows
    rows_N: VertexRows
    pins: CurvePins
    p_NM: np.ndarray
    p_MN: np.ndarray
    fitted: tuple[np.ndarray, np.ndarray] | None = None
    earlier: list[tuple[Any, tuple[np.ndarray, np.ndarray] | PointwiseMaps]] = field(default_factory=list)
    """Earlier stages a refiner keeps for the guard: ``(step, maps)``, or on samples ``(step, fitted maps)`` to
    convert every vertex with when asked for."""

    @property
    def sampled(self) -> bool:
        return not (self.rows_M.all and self.rows_N.all)

    @property
    def maps(self) -> PointwiseMaps:
        return PointwiseMaps(p2p_NM=self.p_NM, p2p_MN=self.p_MN)


class SpectralRefiner(IterativeRefiner[SP, Iterate]):
    """Refinement by alternating functional and pointwise maps (ICP, ZoomOut): each step fits both functional
    maps to the current pointwise maps (:meth:`fit`) and converts them back by nearest neighbours with the curves
    pinned (:meth:`match`). On samples, the last conversion (after the loop, from maps fitted at
    :meth:`final_step`) matches every vertex."""

    def start(
        self, pair: ShapePair, fmaps: FunctionalMaps, params: SP, progress: Progress = no_progress, curves: Curves = ()
    ) -> Start:
        """The vertices to iterate on (``params.samples``, ``params.dense_up_to``), the ``nearest-neighbor`` maps on
        them (``params.search``), bases of :meth:`basis_size` functions and the curves' pins."""
        progress(0.0, "choosing the vertices to iterate on")
        samples = refinement_samples(pair.mesh_M, pair.mesh_N, params.samples, params.dense_up_to)
        progress(0.5, "initial maps (nearest neighbours)")
        maps = initial_maps(pair, fmaps, params.search, samples)
        bases = bases_with(pair, self.basis_size(params), scaled(progress, 0.5, 1.0))
        return Start(maps, CurvePins.from_curves(pair.mesh_M, pair.mesh_N, curves), samples, bases)

    @abstractmethod
    def fit(self, p2p: np.ndarray, domain: VertexRows, image: VertexRows, step: Any, params: SP) -> np.ndarray:
        """The functional map (image -> domain coefficients) fitted to ``p2p`` (domain rows -> image vertices)."""

    @abstractmethod
    def final_step(self, params: SP) -> Any:
        """The step whose fit gives the maps that convert every vertex after a loop on samples."""

    def settled(self, state: Iterate, p_NM: np.ndarray, p_MN: np.ndarray) -> bool:
        """Whether the new maps ``p_NM``, ``p_MN`` end the loop (compared with ``state``'s, still the old ones)."""
        return False

    def both_embeddings(self, params: SP) -> bool:
        """Whether each pointwise map comes from both functional maps at once (else from its own)."""
        return False

    def begin(self, start: Start) -> Iterate:
        """The loop's state from the start: the start's maps with the curves pinned, on the start's rows."""
        assert start.bases is not None, "a spectral refiner starts with bases"
        basis_M, basis_N = start.bases
        ids_M, ids_N = start.samples if start.samples is not None else (None, None)
        rows_M, rows_N = VertexRows(basis_M, ids_M), VertexRows(basis_N, ids_N)
        pins = start.pins
        p_NM, p_MN = pins.pin_NM(start.maps.p2p_NM, rows_N.subset), pins.pin_MN(start.maps.p2p_MN, rows_M.subset)
        return Iterate(rows_M, rows_N, pins, p_NM, p_MN)

    def fit_both(self, state: Iterate, step: Any, params: SP) -> tuple[np.ndarray, np.ndarray]:
        """``C_MN`` (from ``p_NM``) and ``C_NM`` (from ``p_MN``) on the state's rows, each with the curves'
        soft pins weighed in (:meth:`fit_with_evidence`)."""
        pins, rows_M, rows_N = state.pins, state.rows_M, state.rows_N
        return (
            self.fit_with_evidence(state.p_NM, pins.along_NM(state.p_NM, rows_N.subset), rows_N, rows_M, step, params),
            self.fit_with_evidence(state.p_MN, pins.along_MN(state.p_MN, rows_M.subset), rows_M, rows_N, step, params),
        )

    def fit_with_evidence(
        self, p2p: np.ndarray, along: np.ndarray, domain: VertexRows, image: VertexRows, step: Any, params: SP
    ) -> np.ndarray:
        """The map fitted to ``p2p`` and, with weight ``params.curve_interior_weight``, to ``along`` (``p2p`` with
        the curves' inner vertices at their arc-length partners). A fit is linear in its rows, so this is the fit in
        which each inner curve vertex's image is blended with its partner's, the rest unchanged (ICP's
        orthogonalisation makes it a blend of two orthogonal maps)."""
        fitted = self.fit(p2p, domain, image, step, params)
        weight = params.curve_interior_weight
        if weight == 0 or np.array_equal(along, p2p):
            return fitted
        return (1 - weight) * fitted + weight * self.fit(along, domain, image, step, params)

    def match(
        self, fitted: tuple[np.ndarray, np.ndarray], rows_M: VertexRows, rows_N: VertexRows, pins: CurvePins, params: SP
    ) -> tuple[np.ndarray, np.ndarray]:
        """Both pointwise maps on the rows given from the fitted maps, with the curves pinned."""
        C_MN, C_NM = fitted
        both, search = self.both_embeddings(params), params.search
        p_NM = pins.pin_NM(match_rows(C_MN, rows_N, rows_M, search, C_NM if both else None), rows_N.subset)
        p_MN = pins.pin_MN(match_rows(C_NM, rows_M, rows_N, search, C_MN if both else None), rows_M.subset)
        return p_NM, p_MN

    def step(self, state: Iterate, step: Any, params: SP) -> bool:
        state.fitted = self.fit_both(state, step, params)
        p_NM, p_MN = self.match(state.fitted, state.rows_M, state.rows_N, state.pins, params)
        settled = self.settled(state, p_NM, p_MN)
        state.p_NM, state.p_MN = p_NM, p_MN
        return settled

    def every_vertex(self, state: Iterate, fitted: tuple[np.ndarray, np.ndarray], params: SP) -> PointwiseMaps:
        """Both maps on every vertex from ``fitted`` maps, with the curves pinned."""
        every_M, every_N = VertexRows(state.rows_M.basis), VertexRows(state.rows_N.basis)
        p_NM, p_MN = self.match(fitted, every_M, every_N, state.pins, params)
        return PointwiseMaps(p2p_NM=p_NM, p2p_MN=p_MN)

    def finish(self, state: Iterate, params: SP) -> PointwiseMaps:
        """The maps after the loop: the state's own, or on samples every vertex matched from maps fitted once more."""
        if not state.sampled:
            return state.maps
        return self.every_vertex(state, self.fit_both(state, self.final_step(params), params), params)

    def refine(self, start: Start, params: SP, progress: Progress = no_progress) -> PointwiseMaps:
        """The loop from ``start``, then :meth:`finish`."""
        return self.finish(self.iterate(self.begin(start), params, progress), params)

    def convert(
        self, pair: ShapePair, fmaps: FunctionalMaps, params: SP, progress: Progress = no_progress, curves: Curves = ()
    ) -> PointwiseMaps:
        start = self.start(pair, fmaps, params, scaled(progress, 0.0, 0.1), curves)
        return self.refine(start, params, scaled(progress, 0.1, 1.0))
