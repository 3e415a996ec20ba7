"""A session restored from the store: both shapes with their bases (a :class:`~curvefm.spectral.ShapePair`), and
the session's solver rebuilt from them."""

from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from curvefm.errors import Conflict
from curvefm.fmap import (
    CURVES_ALONE_FROM,
    NON_ISOMETRIC_DISTORTION,
    CombinedMapSolver,
    CurveMapSolver,
    EffectiveSolve,
    curves_alone_suffice,
    curves_distortion,
)
from curvefm.session.record import CurveRecord, SessionRecord
from curvefm.spectral import Basis, ShapePair
from curvefm.store import Store


@dataclass(frozen=True)
class BasisNeed:
    """A basis a session needs: on shape ``mesh_id`` (its ``role``, source or target), at least ``k`` functions
    from ``plugin`` with ``params``."""

    mesh_id: str
    role: str
    k: int
    plugin: str
    params: dict[str, Any]

    def describe(self) -> str:
        return f"the {self.role} shape {self.mesh_id} has no '{self.plugin}' basis with k >= {self.k} yet"


class MissingBasis(Conflict):
    """Bases a session needs are not computed yet (``needs`` says which); compute them, then try again."""

    def __init__(self, needs: list[BasisNeed]):
        self.needs = needs
        super().__init__("; ".join(need.describe() for need in needs))


def basis_needs(record: SessionRecord) -> tuple[BasisNeed, BasisNeed]:
    """The bases of the source and the target that the session's solver is built from."""
    k, plugin, params = record.k, record.basis_plugin, record.basis_params
    return BasisNeed(record.source, "source", k, plugin, params), BasisNeed(record.target, "target", k, plugin, params)


def basis_available(store: Store, need: BasisNeed) -> bool:
    """Whether the basis exists (at least ``need.k`` functions), without loading it."""
    return store.has_basis(need.mesh_id, need.k, need.plugin, need.params)


def load_basis(store: Store, need: BasisNeed) -> Basis:
    basis = store.find_basis(need.mesh_id, need.k, need.plugin, need.params)
    if basis is None:
        raise MissingBasis([need])
    return basis


def load_pair(store: Store, record: SessionRecord) -> ShapePair:
    meshes = store.get_mesh(record.source), store.get_mesh(record.target)
    return ShapePair(*meshes, *(load_basis(store, need) for need in basis_needs(record)))


def internal_paths(pair: ShapePair, curve: CurveRecord) -> tuple[np.ndarray, np.ndarray]:
    return (
        pair.mesh_M.internal_ids(curve.path_source, "path vertex"),
        pair.mesh_N.internal_ids(curve.path_target, "path vertex"),
    )


SOLVERS: dict[str, type[CurveMapSolver]] = {"curves": CurveMapSolver, "combined": CombinedMapSolver}


def energy_solver(record: SessionRecord, pair: ShapePair) -> type[CurveMapSolver]:
    """The solver class for the record's energy and curves: a combined session whose curves show the pair strongly
    non-isometric is solved with the curve energy alone (:func:`curvefm.fmap.curves_alone_suffice`), as the
    ``combined`` method does."""
    if record.energy == "combined" and curves_alone_suffice(pair.basis_M, pair.basis_N, _curve_ends(record, pair)):
        return CurveMapSolver
    return SOLVERS[record.energy]


def _curve_ends(record: SessionRecord, pair: ShapePair) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each curve's two ends on both shapes (internal ids): all the isometry rule reads of the curves."""
    return [
        (
            pair.mesh_M.internal_ids([c.path_source[0], c.path_source[-1]]),
            pair.mesh_N.internal_ids([c.path_target[0], c.path_target[-1]]),
        )
        for c in record.curves
    ]


def stated_solve(record: SessionRecord, pair: ShapePair, solver: CurveMapSolver) -> EffectiveSolve:
    """What the session's maps are now (:meth:`CurveMapSolver.effective`), and, where a combined session is solved
    with the curve energy alone (:func:`energy_solver`), why."""
    solve = solver.effective()
    if record.energy == solve.energy:
        return solve
    distortion = curves_distortion(pair.basis_M, pair.basis_N, _curve_ends(record, pair))
    return replace(
        solve,
        summary=f"curves alone (non-isometric pair); {solve.size} x {solve.size}",
        reason=f"combined was asked, but from {CURVES_ALONE_FROM} curves on, a pair whose curves' endpoints show it "
        f"strongly non-isometric (landmark distortion {distortion:.2f} > {NON_ISOMETRIC_DISTORTION:g}) is solved "
        f"with {solve.reason}: the descriptors and the prior assume a near-isometry",
    )


def build_solver(
    record: SessionRecord,
    pair: ShapePair,
    interactive: bool = False,
    executor: Executor | None = None,
    prior_executor: Executor | None = None,
    landmark_prior: bool = True,
) -> CurveMapSolver:
    """The session's solver (:func:`energy_solver`) with all its curves, under the same curve ids as in the record.
    ``prior_executor``: where the combined energy computes its landmark prior (see :class:`CombinedMapSolver`);
    ``landmark_prior=False``: the combined energy without it."""
    solver_class = energy_solver(record, pair)
    background: dict[str, Any] = {}
    if solver_class is CombinedMapSolver and landmark_prior:
        background = {"prior_executor": prior_executor, "source_area": pair.mesh_M.area, "meshes": pair.meshes}
    elif solver_class is CombinedMapSolver:
        background = {"prior_weight": 0.0, "source_area": pair.mesh_M.area}
    solver = solver_class(
        pair.mesh_M.vertices,
        pair.basis_M,
        pair.mesh_N.vertices,
        pair.basis_N,
        k=record.k,
        alpha=record.alpha,
        samples=record.samples,
        interactive=interactive,
        executor=executor,
        **background,
    )
    if record.curves:
        curves = [(*internal_paths(pair, curve), curve.spec.weight) for curve in record.curves]
        solver.add_curves(curves, ids=[curve.id for curve in record.curves])
    return solver
