"""Both shapes of a session with their bases (a :class:`~curvefm.spectral.ShapePair`), loaded from the store, and
the session's solver rebuilt from them."""

from __future__ import annotations

import json

import numpy as np

from curvefm.errors import CurvefmError
from curvefm.fmap import CurveMapSolver
from curvefm.session.record import CurveRecord, SessionRecord
from curvefm.spectral import Basis, ShapePair
from curvefm.store import Store, params_key


def basis_available(store: Store, mesh_id: str, k: int, plugin: str, params: dict) -> bool:
    """Whether a basis with at least k functions exists, without loading it."""
    key = params_key(params)
    return any(b["plugin"] == plugin and b["params_key"] == key and b["k"] >= k for b in store.stored_bases(mesh_id))


def missing_basis_error(mesh_id: str, role: str, k: int, plugin: str, params: dict) -> CurvefmError:
    body = json.dumps({"k": k, "plugin": plugin, "params": params})
    return CurvefmError(
        f"the {role} shape {mesh_id} has no '{plugin}' basis with k >= {k} yet; request it with "
        f"POST /shapes/{mesh_id}/bases {body} and wait for the job to finish",
        kind="conflict",
    )


def load_basis(store: Store, mesh_id: str, role: str, record: SessionRecord) -> Basis:
    basis = store.find_basis(mesh_id, record.k, record.basis_plugin, record.basis_params)
    if basis is None:
        raise missing_basis_error(mesh_id, role, record.k, record.basis_plugin, record.basis_params)
    return basis


def load_pair(store: Store, record: SessionRecord) -> ShapePair:
    return ShapePair(
        store.get_mesh(record.source),
        store.get_mesh(record.target),
        load_basis(store, record.source, "source", record),
        load_basis(store, record.target, "target", record),
    )


def internal_paths(pair: ShapePair, curve: CurveRecord) -> tuple[np.ndarray, np.ndarray]:
    return (
        pair.mesh_M.internal_ids(curve.path_source, "path vertex"),
        pair.mesh_N.internal_ids(curve.path_target, "path vertex"),
    )


def build_solver(
    record: SessionRecord, pair: ShapePair, interactive: bool = False
) -> tuple[CurveMapSolver, dict[str, str]]:
    """The session's solver with all its curves, and the map from session curve ids to solver curve ids."""
    solver = CurveMapSolver(
        pair.mesh_M.vertices,
        pair.basis_M,
        pair.mesh_N.vertices,
        pair.basis_N,
        k=record.k,
        alpha=record.alpha,
        samples=record.samples,
        interactive=interactive,
    )
    if not record.curves:
        return solver, {}
    solver_ids = solver.add_curves([(*internal_paths(pair, curve), curve.spec.weight) for curve in record.curves])
    return solver, dict(zip((curve.id for curve in record.curves), solver_ids, strict=True))
