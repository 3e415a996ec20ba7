"""The operations on sessions: create one, add / replace / remove curves, read the maps, transfer a function,
share one, delete one. (Who may do which is the caller's to decide: the API checks the record's owner and sharing.)

An edit changes the live solver and writes the record (atomically, with the next revision) before it returns,
so an acknowledged edit survives a restart. Edits of one session are serialised by its locks, within the
process and across processes (:meth:`LiveSessions.editing`), and start from the record as last written;
tracing, the slow part, runs before the locks are taken, so edits of different sessions, and the tracing of one,
run in parallel. Curve ids are ``c<n>`` with ``n`` the record's ``next_curve`` (never reused); the solver holds
the curves under the same ids.
"""

from __future__ import annotations

import dataclasses
import functools
import random
import secrets
import time
from collections.abc import Callable
from concurrent.futures import wait
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, ParamSpec, TypeVar

import numpy as np
from pydantic import BaseModel, Field

from curvefm import registry
from curvefm.errors import Conflict, NotFound, RevisionMismatch, StaleRevision, shown
from curvefm.fmap import EffectiveSolve, FunctionTransfer, RoundTripQuality, transposed_basis
from curvefm.geometry import DisplayMesh, Mesh, texture_coordinates
from curvefm.limits import SessionLimits
from curvefm.pointwise import suggest_curve
from curvefm.registry import Plugin
from curvefm.session.curves import CurveSpec, trace_pair
from curvefm.session.live import LiveSession, LiveSessions
from curvefm.session.record import NAME_LENGTH, CurveRecord, Energy, SessionCreate, SessionRecord, Sharing
from curvefm.session.restore import MissingBasis, basis_available, basis_needs, internal_paths, stated_solve
from curvefm.spectral import ShapePair, check_k

if TYPE_CHECKING:
    from sqlalchemy import Connection

    from curvefm.records.sessions import Sessions

TransferFunction = Literal["uv", "xyz", "indicator"]


class SolveStatement(BaseModel):
    """What the session's maps are now, whatever its parameters asked: the energy, its weights and the size the
    maps are handed out at, and why (:meth:`curvefm.fmap.CurveMapSolver.effective`)."""

    energy: Energy = Field(
        description="the energy the maps minimise now: a combined session is solved with the curve energy alone "
        "once its curves show the pair strongly non-isometric"
    )
    weights: dict[str, float] = Field(
        description="its weights as applied now: alpha (Laplacian commutativity; the combined energy uses 30 from "
        "20 curves, whatever the session's alpha), and for combined descriptors, kernels, prior (relative to the "
        "systems' mean diagonal) and high_frequency_damping where applied"
    )
    size: int = Field(
        description="the maps are size x size: the combined energy hands them out at its landmark prior's "
        "min(50, k) below 20 curves, whatever k the session asked"
    )
    summary: str = Field(description="in a few words, e.g. 'combined; 50 x 50 until curves totalling 6.2 sqrt(area)'")
    reason: str = Field(description="why: the rules that chose the energy, its weights and the size")

    @classmethod
    def of(cls, solve: EffectiveSolve) -> SolveStatement:
        return cls(**dataclasses.asdict(solve))


class MapSummary(BaseModel):
    """What an edit reports about the session's maps."""

    revision: int = Field(description="increases with every change of the session")
    n_curves: int
    k: int = Field(description="the session's k (the size asked for; solve.size is the size handed out)")
    solve: SolveStatement = Field(description="the energy, weights and map size after this edit, and why")
    update_ms: float = Field(
        description="time this edit spent updating the maps' curve terms; each map is solved when first read "
        "after the edit (the transfer's X-Solve-Ms header says how long that took)"
    )


@dataclass(frozen=True)
class Transferred:
    """A function carried to the target: float32 ``rows`` per target vertex (internal order), the session
    ``revision`` they reflect, the milliseconds spent solving the map for them (0 when an earlier read had solved
    it), and whether the map will still improve without an edit (``prior_pending``: read again shortly)."""

    rows: np.ndarray
    revision: int
    solve_ms: float
    prior_pending: bool


@dataclass(frozen=True)
class MapQuality:
    """How far the live maps are from being each other's inverse (:mod:`curvefm.fmap.round_trip`): ``drift`` per
    target vertex (float32, internal order or the display vertices', units of ``sqrt(area)``), its area-weighted
    mean ``score`` over the whole target, and the **file** ids of the vertex that drifts furthest clear of the
    curves on each shape (where a new curve helps most). ``prior_pending``: the maps measured are still to improve
    when the landmark prior lands (measure again shortly)."""

    drift: np.ndarray
    score: float
    worst_target: int
    worst_source: int
    revision: int
    prior_pending: bool


class CurveSuggestion(BaseModel):
    """The next curve to draw (:func:`curvefm.pointwise.suggest_curve`): its ends on the source where the live maps
    are least certain, and their images on the target through those maps."""

    revision: int = Field(description="the session revision whose maps made the suggestion")
    source: list[int] = Field(min_length=2, max_length=2, description="file ids of the start and the end on the source")
    target: list[int] = Field(
        min_length=2, max_length=2, description="file ids of their images on the target (the maps' own)"
    )
    prior_pending: bool = Field(
        description="the maps will still improve once the landmark prior for this revision lands: ask again shortly"
    )
    path_source: list[int] | None = Field(
        None,
        description="with paths=true: the curve on the source, file ids from start to end, traced by the session's "
        "tracer as adding it would trace it",
    )
    path_target: list[int] | None = Field(None, description="with paths=true: the curve on the target, likewise")


@dataclass(frozen=True)
class StatedMaps:
    """Both maps of a session, the ``record`` they reflect, and what they are (``solve``)."""

    C_MN: np.ndarray
    C_NM: np.ndarray
    record: SessionRecord
    solve: SolveStatement


STALE_RETRIES = 8
"""How often an edit is tried again when another process wrote the session while it was made."""
P = ParamSpec("P")
T = TypeVar("T")


def _retried(edit: Callable[P, T]) -> Callable[P, T]:
    """Run ``edit`` again (from the record as the other writer left it) when its write finds that another process
    wrote the session since the edit read it; after :data:`STALE_RETRIES` tries the 409 goes to the caller."""

    @functools.wraps(edit)
    def retried(*args: P.args, **kwargs: P.kwargs) -> T:
        for attempt in range(STALE_RETRIES):
            try:
                return edit(*args, **kwargs)
            except StaleRevision:
                if attempt + 1 == STALE_RETRIES:
                    raise
                kwargs.pop("read", None)  # the caller's record is older than the other writer's: read it again
                time.sleep(random.uniform(0, 0.005 * (attempt + 1)))  # two writers retrying apart
        raise AssertionError("unreachable")

    return retried


class SessionEditor:
    """Sessions stored in ``records`` and kept live in ``live``.

    ``find_plugin(kind, name)`` looks plugins up (default :func:`curvefm.registry.get`); the API passes one
    whose error lists the installed plugins. ``limits`` bounds what one request may ask.
    """

    def __init__(
        self,
        records: Sessions,
        live: LiveSessions,
        find_plugin: Callable[[str, str], Plugin[Any]] = registry.get,
        limits: SessionLimits | None = None,
    ):
        self.records, self.live, self.find_plugin = records, live, find_plugin
        self.limits = limits or SessionLimits()

    def create(
        self, request: SessionCreate, session_id: str | None = None, owner: str = "", conn: Connection | None = None
    ) -> SessionRecord:
        """A new session of ``owner``; both shapes must already have bases with at least ``k`` functions. Given a
        transaction ``conn`` the record is stored in it, and the caller prepares the live session once it
        committed (:meth:`LiveSessions.prepare`)."""
        self.find_plugin("tracer", request.tracer)
        basis_params = self.find_plugin("basis", request.basis_plugin).parse_params(request.basis_params)
        now = time.time()
        record = SessionRecord(
            id=session_id or secrets.token_hex(8),
            owner=owner,
            basis_params=basis_params.model_dump(),
            created_at=now,
            updated_at=now,
            name=request.name.strip() or self.default_name(request.source, request.target),
            **request.model_dump(exclude={"basis_params", "name"}),
        )
        self._check_shapes(record)
        self.records.create(record, conn)
        if conn is None:
            self.live.prepare(record.id)
        return record

    def record(self, session_id: str) -> SessionRecord:
        return self.records.read(session_id)

    # -- edits --------------------------------------------------------------------------------------------
    @_retried
    def add_curve(
        self,
        session_id: str,
        spec: CurveSpec,
        curve_id: str | None = None,
        position: int | None = None,
        expected_revision: int | None = None,
        read: SessionRecord | None = None,
    ) -> tuple[CurveRecord, MapSummary]:
        """Add a curve under the next id, at the end of the list. Undoing a delete gives the deleted curve's
        ``curve_id`` back (only an id the session handed out and no curve holds now) and its ``position`` in the
        list (clamped to the list). Each edit given the ``expected_revision`` it was based on is refused
        (:class:`RevisionMismatch`) when the session is at another. ``read``: the record as the caller has just
        read it (to check who asks), saving this edit another read."""
        record = read or self.record(session_id)
        check_revision(record, expected_revision)
        self._check_room(record)
        traced = self._trace(record, spec)
        with self.live.editing(session_id, record) as live:
            check_revision(live.record, expected_revision)
            self._check_room(live.record)
            curve = traced.model_copy(update={"id": curve_id or f"c{live.record.next_curve}"})
            if curve_id is not None:
                _check_returned_id(live.record, curve_id)
            started = time.perf_counter()
            live.solver.add_curve(*internal_paths(live.pair, curve), weight=spec.weight, curve_id=curve.id)
            update_ms = _ms_since(started)
            curves = list(live.record.curves)
            curves.insert(len(curves) if position is None else position, curve)
            changes = {"curves": curves, "next_curve": live.record.next_curve + (curve_id is None)}
            self._commit(live, {"kind": "curve-added", "curve": curve.id}, **changes)
            return curve, _summary(live, update_ms)

    @_retried
    def replace_curve(
        self,
        session_id: str,
        curve_id: str,
        spec: CurveSpec,
        expected_revision: int | None = None,
        read: SessionRecord | None = None,
    ) -> tuple[CurveRecord, MapSummary]:
        record = read or self.record(session_id)
        check_revision(record, expected_revision)
        _require_curve(record, curve_id)
        traced = self._trace(record, spec)
        with self.live.editing(session_id, record) as live:
            check_revision(live.record, expected_revision)
            _require_curve(live.record, curve_id)
            curve = traced.model_copy(update={"id": curve_id})
            started = time.perf_counter()
            live.solver.replace_curve(curve_id, *internal_paths(live.pair, curve), weight=spec.weight)
            update_ms = _ms_since(started)
            curves = [curve if c.id == curve_id else c for c in live.record.curves]
            self._commit(live, {"kind": "curve-replaced", "curve": curve_id}, curves=curves)
            return curve, _summary(live, update_ms)

    @_retried
    def remove_curve(
        self,
        session_id: str,
        curve_id: str,
        expected_revision: int | None = None,
        read: SessionRecord | None = None,
    ) -> MapSummary:
        with self.live.editing(session_id, read) as live:
            check_revision(live.record, expected_revision)
            _require_curve(live.record, curve_id)
            started = time.perf_counter()
            live.solver.remove_curve(curve_id)
            update_ms = _ms_since(started)
            curves = [c for c in live.record.curves if c.id != curve_id]
            self._commit(live, {"kind": "curve-removed", "curve": curve_id}, curves=curves)
            return _summary(live, update_ms)

    @_retried
    def default_name(self, source: str, target: str) -> str:
        """ "SOURCE -> TARGET", the shapes' names (their ids' starts when they have none)."""
        sides = ((source, "source"), (target, "target"))
        return " -> ".join(self.live.mesh(shape, role).name or shape[:12] for shape, role in sides)[:NAME_LENGTH]

    def rename(self, session_id: str, name: str) -> SessionRecord:
        """Give the session another name (the record alone is written, as for :meth:`share`)."""
        with self.live.locked(session_id), self.records.locked(session_id):
            record = self.records.write(self.records.read(session_id).model_copy(update={"name": name}))
        self.live.notify(session_id, {"kind": "renamed", "revision": record.revision})
        return record

    def share(self, session_id: str, sharing: Sharing) -> SessionRecord:
        """Change who may use the session. Only the record is written: a live session takes the new revision up
        on its next use, as after another process's edit."""
        with self.live.locked(session_id), self.records.locked(session_id):
            record = self.records.write(self.records.read(session_id).model_copy(update={"sharing": sharing}))
        self.live.notify(session_id, {"kind": "sharing", "revision": record.revision, "sharing": sharing})
        return record

    def delete(self, session_id: str) -> list[str]:
        """Delete the session; returns the ids of the refinement jobs run from it."""
        with self.live.locked(session_id), self.records.locked(session_id):
            self.live.drop(session_id)
            jobs = self.records.delete(session_id)
        self.live.notify(session_id, {"kind": "deleted", "revision": None})
        return jobs

    # -- maps and transfer --------------------------------------------------------------------------------
    def maps(self, session_id: str) -> tuple[np.ndarray, np.ndarray, SessionRecord]:
        """``(C_MN, C_NM, record)``: both final maps (their landmark prior computed) and the record they reflect."""
        maps = self.stated_maps(session_id)
        return maps.C_MN, maps.C_NM, maps.record

    def stated_maps(self, session_id: str) -> StatedMaps:
        """Both final maps, the record they reflect and what they are (:class:`StatedMaps`)."""
        with self.live.using(session_id) as live:
            live.solver.settle()
            return StatedMaps(live.solver.C_MN, live.solver.C_NM, live.record, _stated(live))

    def solve(self, session_id: str) -> SolveStatement:
        """What the session's maps are now (energy, weights, size) and why, without solving them."""
        with self.live.using(session_id) as live:
            return _stated(live)

    def transfer(
        self, session_id: str, function: TransferFunction, vertices: list[int] | None = None, display: bool = False
    ) -> Transferred:
        """``function`` on the source carried to the target through the live map (see :class:`Transferred`).

        ``display``: rows at the target's display vertices only (:meth:`LiveSessions.display`; all rows when it
        is drawn whole), computed from those rows of its basis alone; and an indicator's ``vertices``, picked on
        the source's display copy, each stand for the part of the source nearest to them."""
        with self.live.using(session_id) as live:
            # pending first: a prior landing between the two reads then costs the client one more read, not the map
            prior_pending, solving = live.solver.prior_pending, "MN" in live.solver.pending
            live.watched = True
            C_MN, revision = live.solver.C_MN, live.record.revision
            solve_ms = live.solver.last_solve_ms if solving else 0.0
        spread = self.live.display(live.record.source, "source") if display and function == "indicator" else None
        key = (function, tuple(vertices or ()), spread is not None)
        carried = live.transfers.get(key, lambda: _projected(live, function, vertices, spread))
        values = carried.apply(C_MN, self._display_rows(live) if display else None)
        rows = np.ascontiguousarray(values.reshape(len(values), -1), dtype=np.float32)
        return Transferred(rows, revision, solve_ms, prior_pending)

    def quality(self, session_id: str, display: bool = False) -> MapQuality:
        """The round-trip quality of the live maps. It needs ``C_NM``, which an interactive solver solves now if
        the last edit deferred it. ``display``: the drift at the target's display vertices only (the score and
        the worst vertices are the whole shapes' all the same)."""
        with self.live.using(session_id) as live:
            prior_pending = live.solver.prior_pending  # first: a prior landing meanwhile costs one more read
            C_MN, C_NM, record, measure = live.solver.C_MN, live.solver.C_NM, live.record, live.round_trip
        curves_M, curves_N = _curve_vertices(live.pair, record)
        found = measure.measure(C_MN, C_NM, curves_M, curves_N)
        shown = self.live.display(record.target, "target") if display else None
        return MapQuality(
            drift=found.target if shown is None else found.target[shown.vertex_ids],
            score=found.score,
            worst_target=int(live.pair.mesh_N.file_ids[found.worst_target]),
            worst_source=int(live.pair.mesh_M.file_ids[found.worst_source]),
            revision=record.revision,
            prior_pending=prior_pending,
        )

    def suggestion(
        self, session_id: str, paths: bool = False, ends: tuple[list[int], list[int]] | None = None
    ) -> CurveSuggestion:
        """Where one more curve helps most, from the live maps (both solved now if an edit deferred them).
        ``ends``: (source, target) file ids of ends the person moved, kept instead of suggesting new ones (and
        traced). ``paths``: with the curve traced between the ends as adding it traces it (once, no lock held)."""
        with self.live.using(session_id) as live:
            prior_pending = live.solver.prior_pending  # first: a prior landing meanwhile costs one more read
            C_MN, C_NM, record, measure = live.solver.C_MN, live.solver.C_NM, live.record, live.round_trip
        source, target = ends or self._suggested_ends(live.pair, C_MN, C_NM, measure, record)
        traced = self._trace(record, CurveSpec(source=source, target=target)) if paths or ends else None
        return CurveSuggestion(
            revision=record.revision,
            source=source,
            target=target,
            prior_pending=prior_pending,
            path_source=None if traced is None else traced.path_source.tolist(),
            path_target=None if traced is None else traced.path_target.tolist(),
        )

    # -- internals ----------------------------------------------------------------------------------------
    @staticmethod
    def _suggested_ends(
        pair: ShapePair, C_MN: np.ndarray, C_NM: np.ndarray, measure: RoundTripQuality, record: SessionRecord
    ) -> tuple[list[int], list[int]]:
        """The suggested ends, (source, target) file ids."""
        curves_M, curves_N = _curve_vertices(pair, record)
        drift = measure.measure(C_MN, C_NM, curves_M, curves_N)
        found = suggest_curve(pair, C_MN, C_NM, drift.source, curves_M)
        return pair.mesh_M.file_ids[list(found.source)].tolist(), pair.mesh_N.file_ids[list(found.target)].tolist()

    def _display_rows(self, live: LiveSession) -> np.ndarray | None:
        """The target's basis at its display vertices (:func:`transposed_basis`, made once per session: reading
        these rows alone is what makes a display transfer cheap), or ``None`` when the target is drawn whole."""
        shown = self.live.display(live.record.target, "target")
        if shown is None:
            return None
        return live.display_rows.get(shown.key, lambda: transposed_basis(live.solver.basis_N.evecs[shown.vertex_ids]))

    def _check_shapes(self, record: SessionRecord) -> None:
        """Both shapes exist, can have ``k`` basis functions, and have them already."""
        needs = basis_needs(record)
        for need in needs:
            mesh = self.live.mesh(need.mesh_id, need.role)
            check_k(record.k, mesh.n_vertices, mesh.name or need.mesh_id)
        self.limits.check("max_k", record.k, f"k = {record.k} basis functions")
        missing = [need for need in needs if not basis_available(self.live.store, need)]
        if missing:
            raise MissingBasis(missing)

    def _trace(self, record: SessionRecord, spec: CurveSpec) -> CurveRecord:
        """Trace a curve pair (no lock held). The returned record's id is a placeholder."""
        tracer = spec.tracer or record.tracer
        if spec.tracer or spec.traced:  # a tracer named with an explicit path is checked all the same
            self.find_plugin("tracer", tracer).parse_params(spec.tracer_params)
        for side, ids in (("source", spec.source), ("target", spec.target)):
            if spec.is_path(side):
                self.limits.check("max_path_vertices", len(ids), f"{len(ids)} vertices in the {side} path")
            else:
                self.limits.check("max_waypoints", len(ids), f"{len(ids)} waypoints on the {side}")
        mesh_M, mesh_N = self.live.mesh(record.source, "source"), self.live.mesh(record.target, "target")
        guides = self.live.guide(record.source), self.live.guide(record.target)
        path_M, path_N = trace_pair(mesh_M, mesh_N, spec, record.tracer, guides)
        for side, path in (("source", path_M), ("target", path_N)):
            self.limits.check("max_path_vertices", len(path), f"{len(path)} vertices in the traced {side} path")
        return CurveRecord(
            id="new",
            spec=spec,
            tracer=tracer if spec.traced else "explicit",
            path_source=mesh_M.file_ids[path_M],
            path_target=mesh_N.file_ids[path_N],
        )

    def _check_room(self, record: SessionRecord) -> None:
        """Room for one more curve in the session."""
        count = len(record.curves) + 1
        self.limits.check("max_curves", count, f"{count} curves in session {record.id}")

    def _commit(self, live: LiveSession, event: dict[str, Any], **changes: Any) -> None:
        """Write the edited record, then make it the live one; when its texture was read since the last edit (the
        web UI reads it after each, or has it carried in the edit's answer), have the new map solved on another
        thread while the record is written (the durable write mostly waits for the disk), so the answer, or the
        next read, finds it solved (a script that only edits leaves the solves to its reads, if any). If writing
        fails the solver already holds the edit, so the live session is dropped and rebuilt from the database on
        next use: so when another process wrote the session since this edit read it (the write's revision check
        fails, a 409 that says to try again; the retry starts from the other process's revision)."""
        solving = self.live.solve_beside(live) if live.watched else None
        live.watched = False
        try:
            live.record = self.records.write(live.record.model_copy(update=changes), base=live.record)
        except BaseException:
            self.live.drop(live.record.id)
            raise
        finally:
            if solving is not None:
                wait([solving])  # the solver is the edit's again
        self.live.notify(live.record.id, {**event, "revision": live.record.revision})
        self.live.fit_energy(live)


def source_function(
    mesh: Mesh, function: TransferFunction, vertices: list[int] | None = None, spread: DisplayMesh | None = None
) -> np.ndarray:
    """Per-vertex values on the source: its uv (or generated cylindrical uv), its coordinates scaled to [0, 1]
    per axis, or the indicator of some vertices (file ids; of none: zero everywhere), each with the part of the
    mesh nearest to it on the display copy ``spread`` when given."""
    if function == "uv":
        return texture_coordinates(mesh)
    if function == "xyz":
        low = mesh.vertices.min(axis=0)
        return (mesh.vertices - low) / np.maximum(np.ptp(mesh.vertices, axis=0), 1e-300)
    values = np.zeros(mesh.n_vertices)
    if vertices:
        ids = mesh.internal_ids(vertices, "indicator vertex")
        values[ids if spread is None else spread.region_of(ids)] = 1.0
    return values


def _curve_vertices(pair: ShapePair, record: SessionRecord) -> tuple[np.ndarray, np.ndarray]:
    """The internal ids of every curve's path vertices on the source and on the target."""
    paths = [(curve.path_source, curve.path_target) for curve in record.curves]
    on_M = np.concatenate([[], *(source for source, _ in paths)]).astype(np.int64)
    on_N = np.concatenate([[], *(target for _, target in paths)]).astype(np.int64)
    return pair.mesh_M.internal_ids(on_M, "path vertex"), pair.mesh_N.internal_ids(on_N, "path vertex")


def _projected(
    live: LiveSession, function: TransferFunction, vertices: list[int] | None, spread: DisplayMesh | None
) -> FunctionTransfer:
    values = source_function(live.pair.mesh_M, function, vertices, spread)
    return FunctionTransfer(live.solver.basis_M, live.solver.basis_N, values)


def check_revision(record: SessionRecord, expected: int | None) -> None:
    """The session is at the ``expected`` revision (when one is given), else :class:`RevisionMismatch`."""
    if expected is not None and record.revision != expected:
        raise RevisionMismatch("session", record.id, expected, record.revision)


def _require_curve(record: SessionRecord, curve_id: str) -> None:
    if all(c.id != curve_id for c in record.curves):
        ids = ", ".join(c.id for c in record.curves) or "none yet"
        raise NotFound(f"no curve '{shown(curve_id)}' in session {record.id}; its curves: {ids}")


def _check_returned_id(record: SessionRecord, curve_id: str) -> None:
    """``curve_id`` (``c<n>``) was handed out by the session and is free again (its curve was deleted)."""
    if any(c.id == curve_id for c in record.curves):
        raise Conflict(f"curve id '{shown(curve_id)}' is in use in session {record.id}; give another or none")
    if not curve_id.startswith("c") or not curve_id[1:].isdigit() or int(curve_id[1:]) >= record.next_curve:
        raise Conflict(
            f"session {record.id} never had a curve '{shown(curve_id)}'; only a deleted curve's id can "
            "be given back (to undo its deletion), or none for a new one"
        )


def _summary(live: LiveSession, update_ms: float) -> MapSummary:
    record = live.record
    return MapSummary(
        revision=record.revision, n_curves=len(record.curves), k=record.k, solve=_stated(live), update_ms=update_ms
    )


def _stated(live: LiveSession) -> SolveStatement:
    return SolveStatement.of(stated_solve(live.record, live.pair, live.solver))


def _ms_since(started: float) -> float:
    return round((time.perf_counter() - started) * 1000, 3)
