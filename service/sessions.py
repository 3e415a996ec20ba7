"""Sessions: durable records on disk, live solvers in memory.

A session's record (:class:`SessionRecord`) is the truth; it is rewritten atomically in
``<data>/sessions/<id>.json`` before an edit is acknowledged. Solvers, bases, meshes and projected transfer
functions are caches, rebuilt lazily from the store. Edits of one session are serialised by its lock; tracing
runs before taking it, so edits of different sessions (and the slow part of one) proceed in parallel.
"""

from __future__ import annotations

import re
import secrets
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from curvefm.errors import CurvefmError
from curvefm.fmap import CurveMapSolver, FunctionTransfer
from curvefm.geometry import Mesh, texture_coordinates
from curvefm.service.cache import LRU
from curvefm.service.errors import require_plugin
from curvefm.service.models import MapSummary, SessionCreate
from curvefm.session import (
    CurveRecord,
    CurveSpec,
    SessionRecord,
    ShapePair,
    basis_available,
    build_solver,
    load_basis,
    missing_basis_error,
    trace_pair,
)
from curvefm.spectral import Basis, check_k
from curvefm.store import Store, atomic_write, params_key

TransferFunction = Literal["uv", "xyz", "indicator"]
_SESSION_ID = re.compile(r"^[A-Za-z0-9_-]{1,64}$")


@dataclass
class LiveSession:
    record: SessionRecord
    pair: ShapePair
    solver: CurveMapSolver
    solver_ids: dict[str, str]  # session curve id -> solver curve id
    transfers: LRU[FunctionTransfer]


class SessionManager:
    def __init__(self, store: Store, cache_size: int = 32):
        self.store = store
        self.folder = store.root / "sessions"
        self._meshes: LRU[Mesh] = LRU(16)
        self._bases: LRU[Basis] = LRU(8)
        self._live: LRU[LiveSession] = LRU(cache_size)
        self._locks: dict[str, threading.Lock] = {}
        self._locks_guard = threading.Lock()

    # -- shapes -------------------------------------------------------------------------------------------
    def mesh(self, mesh_id: str, role: str = "") -> Mesh:
        if not self.store.has_mesh(mesh_id):
            what = f"{role} shape" if role else "shape"
            raise CurvefmError(f"no {what} with id '{mesh_id}'; upload it with POST /shapes", kind="not_found")
        return self._meshes.get(mesh_id, lambda: self.store.get_mesh(mesh_id))

    def _basis(self, mesh_id: str, role: str, record: SessionRecord) -> Basis:
        key = (mesh_id, record.basis_plugin, params_key(record.basis_params), record.k)
        return self._bases.get(key, lambda: load_basis(self.store, mesh_id, role, record))

    # -- records ------------------------------------------------------------------------------------------
    def create(self, request: SessionCreate, session_id: str | None = None) -> SessionRecord:
        """A new session; both shapes must already have bases with at least ``k`` functions."""
        require_plugin("tracer", request.tracer)
        basis_params = require_plugin("basis", request.basis_plugin).parse_params(request.basis_params).model_dump()
        missing = []
        for role, mesh_id in (("source", request.source), ("target", request.target)):
            mesh = self.mesh(mesh_id, role)
            check_k(request.k, mesh.n_vertices, mesh.name or mesh_id)
            if not basis_available(self.store, mesh_id, request.k, request.basis_plugin, basis_params):
                missing.append(missing_basis_error(mesh_id, role, request.k, request.basis_plugin, basis_params))
        if missing:
            raise CurvefmError("; ".join(error.message for error in missing), kind="conflict")
        now = time.time()
        record = SessionRecord(
            id=session_id or secrets.token_hex(8),
            basis_params=basis_params,
            created_at=now,
            updated_at=now,
            **request.model_dump(exclude={"basis_params"}),
        )
        with self._lock(record.id):
            if self._path(record.id).exists():
                raise CurvefmError(f"session '{record.id}' already exists", kind="conflict")
            self._persist(record)
            self._load(record.id)  # bases loaded and solver built now, not on the first curve
        return record

    def record(self, session_id: str) -> SessionRecord:
        with self._lock(session_id):
            live = self._live.peek(session_id)
            return live.record if live is not None else self._read(session_id)

    def exists(self, session_id: str) -> bool:
        return bool(_SESSION_ID.match(session_id)) and self._path(session_id).is_file()

    def list(self) -> list[SessionRecord]:
        records = [SessionRecord.model_validate_json(p.read_bytes()) for p in self.folder.glob("*.json")]
        return sorted(records, key=lambda r: r.updated_at, reverse=True)

    # -- edits --------------------------------------------------------------------------------------------
    def add_curve(self, session_id: str, spec: CurveSpec) -> tuple[CurveRecord, MapSummary]:
        traced = self._trace(session_id, spec)
        with self._lock(session_id):
            live = self._load(session_id)
            curve = traced.model_copy(update={"id": f"c{live.record.next_curve}"})
            started = time.perf_counter()
            solver_id = live.solver.add_curve(*self._internal(live, curve), weight=spec.weight)
            solve_ms = _ms_since(started)
            record = live.record.model_copy(
                update={"curves": [*live.record.curves, curve], "next_curve": live.record.next_curve + 1}
            )
            self._commit(live, record)
            live.solver_ids[curve.id] = solver_id
            return curve, self._summary(live, solve_ms)

    def replace_curve(self, session_id: str, curve_id: str, spec: CurveSpec) -> tuple[CurveRecord, MapSummary]:
        self._require_curve(self.record(session_id), curve_id)
        traced = self._trace(session_id, spec)
        with self._lock(session_id):
            live = self._load(session_id)
            self._require_curve(live.record, curve_id)
            curve = traced.model_copy(update={"id": curve_id})
            started = time.perf_counter()
            live.solver.replace_curve(live.solver_ids[curve_id], *self._internal(live, curve), weight=spec.weight)
            solve_ms = _ms_since(started)
            curves = [curve if c.id == curve_id else c for c in live.record.curves]
            self._commit(live, live.record.model_copy(update={"curves": curves}))
            return curve, self._summary(live, solve_ms)

    def remove_curve(self, session_id: str, curve_id: str) -> MapSummary:
        with self._lock(session_id):
            live = self._load(session_id)
            self._require_curve(live.record, curve_id)
            started = time.perf_counter()
            live.solver.remove_curve(live.solver_ids[curve_id])
            solve_ms = _ms_since(started)
            curves = [c for c in live.record.curves if c.id != curve_id]
            self._commit(live, live.record.model_copy(update={"curves": curves}))
            del live.solver_ids[curve_id]
            return self._summary(live, solve_ms)

    # -- maps and transfer --------------------------------------------------------------------------------
    def maps(self, session_id: str) -> tuple[np.ndarray, np.ndarray, SessionRecord]:
        with self._lock(session_id):
            live = self._load(session_id)
            return live.solver.C_MN, live.solver.C_NM, live.record

    def transfer(
        self, session_id: str, function: TransferFunction, vertices: list[int] | None = None
    ) -> tuple[np.ndarray, int]:
        """``function`` on the source carried to the target: float32 rows per target vertex (internal
        order), and the session revision it reflects."""
        with self._lock(session_id):
            live = self._load(session_id)
            C_MN, revision = live.solver.C_MN, live.record.revision
        key = (function, tuple(vertices or ()))
        carried = live.transfers.get(key, lambda: self._projected(live, function, vertices))
        values = carried.apply(C_MN)
        return np.ascontiguousarray(values.reshape(len(values), -1), dtype=np.float32), revision

    # -- internals ----------------------------------------------------------------------------------------
    def _lock(self, session_id: str) -> threading.Lock:
        if not _SESSION_ID.match(session_id):
            raise _unknown_session(session_id)
        with self._locks_guard:
            return self._locks.setdefault(session_id, threading.Lock())

    def _path(self, session_id: str) -> Path:
        return self.folder / f"{session_id}.json"

    def _read(self, session_id: str) -> SessionRecord:
        path = self._path(session_id)
        if not path.is_file():
            raise _unknown_session(session_id)
        return SessionRecord.model_validate_json(path.read_bytes())

    def _persist(self, record: SessionRecord) -> None:
        atomic_write(self._path(record.id), record.model_dump_json(indent=1).encode())

    def _load(self, session_id: str) -> LiveSession:
        """The live session (caller holds its lock), rebuilt from disk when not cached."""
        return self._live.get(session_id, lambda: self._build(session_id))

    def _build(self, session_id: str) -> LiveSession:
        record = self._read(session_id)
        pair = ShapePair(
            self.mesh(record.source, "source"),
            self.mesh(record.target, "target"),
            self._basis(record.source, "source", record),
            self._basis(record.target, "target", record),
        )
        # an edit solves only the map the texture needs, on one thread: with the cores shared (other sessions,
        # or the browser in bench_ui_latency) that took the solve from 11-13 to 8 ms
        solver, solver_ids = build_solver(record, pair, interactive=True)
        for mesh in pair.meshes:
            mesh.edge_graph  # noqa: B018  (cached property: built here so the first trace answers at once)
        return LiveSession(record, pair, solver, solver_ids, LRU(8))

    def _commit(self, live: LiveSession, record: SessionRecord) -> None:
        """Persist the edited record, then make it the live one. If writing fails the solver already holds
        the edit, so the live session is dropped and rebuilt from disk on next use."""
        record = record.model_copy(update={"revision": record.revision + 1, "updated_at": time.time()})
        try:
            self._persist(record)
        except BaseException:
            self._live.pop(record.id)
            raise
        live.record = record

    def _trace(self, session_id: str, spec: CurveSpec) -> CurveRecord:
        """Trace a curve pair (no lock held). The returned record's id is a placeholder."""
        record = self.record(session_id)
        tracer = spec.tracer or record.tracer
        if not spec.explicit:
            require_plugin("tracer", tracer)
        mesh_M, mesh_N = self.mesh(record.source, "source"), self.mesh(record.target, "target")
        path_M, path_N = trace_pair(mesh_M, mesh_N, spec, record.tracer)
        return CurveRecord(
            id="new",
            spec=spec,
            tracer="explicit" if spec.explicit else tracer,
            path_source=mesh_M.file_ids[path_M].tolist(),
            path_target=mesh_N.file_ids[path_N].tolist(),
        )

    @staticmethod
    def _internal(live: LiveSession, curve: CurveRecord) -> tuple[np.ndarray, np.ndarray]:
        return (
            live.pair.mesh_M.internal_ids(curve.path_source, "path vertex"),
            live.pair.mesh_N.internal_ids(curve.path_target, "path vertex"),
        )

    @staticmethod
    def _require_curve(record: SessionRecord, curve_id: str) -> None:
        if all(c.id != curve_id for c in record.curves):
            ids = ", ".join(c.id for c in record.curves) or "none yet"
            raise CurvefmError(f"no curve '{curve_id}' in session {record.id}; its curves: {ids}", kind="not_found")

    @staticmethod
    def _summary(live: LiveSession, solve_ms: float) -> MapSummary:
        return MapSummary(
            revision=live.record.revision,
            n_curves=len(live.record.curves),
            k=live.record.k,
            solve_ms=solve_ms,
        )

    def _projected(self, live: LiveSession, function: TransferFunction, vertices: list[int] | None):
        values = source_function(live.pair.mesh_M, function, vertices)
        return FunctionTransfer(live.solver.basis_M, live.solver.basis_N, values)


def source_function(mesh: Mesh, function: TransferFunction, vertices: list[int] | None = None) -> np.ndarray:
    """Per-vertex values on the source: its uv (or generated cylindrical uv), its coordinates scaled to [0, 1]
    per axis, or the indicator of some vertices (file ids)."""
    if function == "uv":
        return texture_coordinates(mesh)
    if function == "xyz":
        low = mesh.vertices.min(axis=0)
        return (mesh.vertices - low) / np.maximum(np.ptp(mesh.vertices, axis=0), 1e-300)
    if not vertices:
        raise CurvefmError("function=indicator needs vertices, e.g. &vertices=12,345 (file ids on the source)")
    values = np.zeros(mesh.n_vertices)
    values[mesh.internal_ids(vertices, "indicator vertex")] = 1.0
    return values


def _unknown_session(session_id: str) -> CurvefmError:
    return CurvefmError(f"no session with id '{session_id}'; GET /sessions lists them", kind="not_found")


def _ms_since(started: float) -> float:
    return round((time.perf_counter() - started) * 1000, 3)
