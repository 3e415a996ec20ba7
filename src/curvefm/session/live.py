"""Live sessions: what a long-running process (the API) keeps in memory for the sessions in use.

A live session is its record, its shapes with their bases and its solver with every curve, plus the functions
projected for transfer. All of it is a cache, rebuilt from the store on demand: the record on disk is the
truth. :class:`LiveSessions` bounds everything it holds (least recently used go first), hands its solvers one
executor it owns, and serialises the use of each session through a fixed set of locks: session ``s`` uses lock
``crc32(s) % 64``, so the lock table does not grow with the ids asked for. Two sessions rarely contend: at the
load budget (50 sessions editing twice a second, about 10 ms an edit) an edit finds its lock held by another
session's edit about 1 time in 65.

Other processes may edit the same sessions (several API processes on one database). So every use starts by
reading the record's revision (:meth:`Sessions.read_changed <curvefm.records.sessions.Sessions.read_changed>`); a
live session behind it is brought up to date (:meth:`CurveMapSolver.sync <curvefm.fmap.CurveMapSolver.sync>`
recomputes only the curves that changed), and an edit's write checks that the revision it started from is still
the stored one (another process's write in between makes it :class:`~curvefm.errors.StaleRevision`).
"""

from __future__ import annotations

import logging
import os
import threading
import zlib
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cached_property, partial
from typing import TYPE_CHECKING, Any

import numpy as np

from curvefm.cache import LRU
from curvefm.errors import NotFound, Unavailable, shown
from curvefm.fmap import CombinedMapSolver, CurveMapSolver, FunctionTransfer, RoundTripQuality
from curvefm.geometry import DisplayMesh, Mesh, display_graph
from curvefm.session.record import SessionRecord
from curvefm.session.restore import (
    BasisNeed,
    basis_needs,
    build_solver,
    energy_solver,
    internal_paths,
    load_basis,
)
from curvefm.spectral import Basis, ShapePair
from curvefm.store import Store, params_key

if TYPE_CHECKING:
    from curvefm.records.sessions import Sessions

LOCK_STRIPES = 64
DEFAULT_LOCK_TIMEOUT_S = 30.0
"""How long an edit waits for another request's edit of the same session (``CURVEFM_SESSION_LOCK_TIMEOUT``)."""

log = logging.getLogger(__name__)


class SessionBusy(Unavailable):
    """A session was held by another request of this process for longer than the configured wait."""

    def __init__(self, session_id: str, timeout_s: float):
        super().__init__(
            f"session {session_id} is busy: another request held it for more than {timeout_s:g} s "
            f"(session_lock_timeout; set CURVEFM_SESSION_LOCK_TIMEOUT to change it); try again"
        )


class UnknownShape(NotFound):
    """No stored shape has this id."""

    def __init__(self, mesh_id: str, role: str = ""):
        self.mesh_id, self.role = mesh_id, role
        super().__init__(f"no {role + ' ' if role else ''}shape with id '{shown(mesh_id)}'")


@dataclass
class LiveSession:
    record: SessionRecord
    pair: ShapePair
    solver: CurveMapSolver
    transfers: LRU[FunctionTransfer]  # by (function, vertices, spread): the function on M projected on M's basis
    display_rows: LRU[np.ndarray]  # by display copy key: N's basis at the target's display vertices (transposed_basis)
    # someone reads its texture between edits (the web UI, after each): its next edit's map is solved at once
    watched: bool = False

    @cached_property
    def round_trip(self) -> RoundTripQuality:
        """The maps' round-trip quality measure, built on first use (under the session's lock)."""
        return RoundTripQuality(self.pair.mesh_M, self.solver.basis_M, self.pair.mesh_N, self.solver.basis_N)


class LiveSessions:
    """Live sessions (at most ``size``), the meshes and bases they use, and the locks that serialise them.
    Meshes with more than ``display_vertices`` vertices are drawn as a display copy of about that many
    (:mod:`curvefm.geometry.display`; 0: every mesh is drawn whole); on meshes of at least
    ``guided_trace_vertices`` whose display copy is stored, curves are traced near it (:meth:`guide`). Sessions
    on meshes of more than ``prior_max_vertices`` vertices solve the combined energy without its landmark prior."""

    def __init__(
        self,
        store: Store,
        records: Sessions,
        size: int = 32,
        display_vertices: int = 0,
        prior_max_vertices: int = 150_000,
        guided_trace_vertices: int = 300_000,
    ):
        self.store, self.records = store, records
        self.display_vertices, self.prior_max_vertices = display_vertices, prior_max_vertices
        self.guided_trace_vertices = guided_trace_vertices
        self._meshes: LRU[Mesh] = LRU(16)
        self._displays: LRU[DisplayMesh] = LRU(16)  # by mesh id: seconds to make at scan size, so kept apart
        self._bases: LRU[Basis] = LRU(8)
        self._sessions: LRU[LiveSession] = LRU(size)
        self._locks = tuple(threading.Lock() for _ in range(LOCK_STRIPES))
        self._executor = ThreadPoolExecutor(2, thread_name_prefix="curvefm-columns")
        # one thread for every session's landmark prior (about 0.5 s each), at low priority, so that it never delays
        # a column solve or a trace
        self._prior_executor = ThreadPoolExecutor(1, thread_name_prefix="curvefm-priors", initializer=_lower_priority)
        self.notify: SessionNotify = _nobody
        """Told of a session's change that its record does not show: its landmark prior landed (maps improved)."""

    def lock(self, session_id: str) -> threading.Lock:
        """The lock to hold while using or changing session ``session_id``."""
        return self._locks[zlib.crc32(session_id.encode()) % len(self._locks)]

    @contextmanager
    def locked(self, session_id: str) -> Iterator[None]:
        """Hold the session's lock, waiting at most the records' ``lock_timeout_s`` (then :class:`SessionBusy`)."""
        lock = self.lock(session_id)
        if not lock.acquire(timeout=self.records.lock_timeout_s):
            raise SessionBusy(shown(session_id), self.records.lock_timeout_s)
        try:
            yield
        finally:
            lock.release()

    @contextmanager
    def editing(self, session_id: str, read: SessionRecord | None = None) -> Iterator[LiveSession]:
        """The live session, up to date with its record, held for an edit against this process's other threads
        (the session's lock) until the edit is written; other processes' edits are caught by the write's revision
        check. ``read``: the record as the caller read it for this edit, which the live session is brought up to
        instead of reading it again (a later write by another process fails the edit's write, which is retried)."""
        with self.locked(session_id):
            yield self._current(session_id, read)  # (an unknown or deleted session raises there)

    @contextmanager
    def using(self, session_id: str) -> Iterator[LiveSession]:
        """The live session, up to date with its record, held against this process's other threads (reading
        needs no file lock: a record is replaced whole)."""
        with self.locked(session_id):
            yield self._current(session_id)

    def solve_beside(self, live: LiveSession) -> Future[None]:
        """Solve the session's map ``C_MN`` (the one the texture is carried by; 7-9 ms at k = 120) on another
        thread, beside the caller's work: the caller holds the session's lock and leaves its solver alone until
        the future is done."""
        return self._executor.submit(_solve_map, live.solver)

    def prepare(self, session_id: str) -> None:
        """Load the session's bases and build its solver now, so that its first edit answers at once."""
        with self.using(session_id):
            pass

    def peek(self, session_id: str) -> LiveSession | None:
        return self._sessions.peek(session_id)

    def drop(self, session_id: str) -> None:
        """Forget the live session: it is rebuilt from disk on next use."""
        self._sessions.pop(session_id)

    def mesh(self, mesh_id: str, role: str = "") -> Mesh:
        """A stored mesh; ``role`` (source or target) names it in the error when there is none."""
        if not self.store.has_mesh(mesh_id):
            raise UnknownShape(mesh_id, role)
        return self._meshes.get(mesh_id, lambda: self.store.get_mesh(mesh_id))

    def display(self, mesh_id: str, role: str = "") -> DisplayMesh | None:
        """The display copy of a stored mesh, made on first use (1-2 s at 110k vertices, 10 s at 440k) and kept in
        the store, so other processes and later starts read it; ``None`` when it is drawn whole."""
        mesh = self.mesh(mesh_id, role)
        if not 0 < self.display_vertices < mesh.n_vertices:
            return None
        return self._displays.get(mesh_id, lambda: self.store.ensure_display(mesh, self.display_vertices))

    def guide(self, mesh_id: str) -> DisplayMesh | None:
        """The display copy to trace near on a mesh of at least ``guided_trace_vertices``, when one is made
        already (its basis job makes it; an edit never waits for one): else ``None``, traced on the whole mesh."""
        mesh = self.mesh(mesh_id)
        if mesh.n_vertices < self.guided_trace_vertices or not 0 < self.display_vertices < mesh.n_vertices:
            return None
        made = self._displays.peek(mesh_id)
        if made is None and (made := self.store.find_display(mesh, self.display_vertices)) is not None:
            self._displays.put(mesh_id, made)
        return made

    def basis(self, need: BasisNeed) -> Basis:
        key = (need.mesh_id, need.plugin, params_key(need.params), need.k)
        return self._bases.get(key, lambda: load_basis(self.store, need))

    def close(self) -> None:
        """Forget every live session and stop the solvers' executor."""
        self._sessions.clear()
        self._executor.shutdown()
        self._prior_executor.shutdown(cancel_futures=True)

    def _current(self, session_id: str, read: SessionRecord | None = None) -> LiveSession:
        """The live session as of its record on disk (or as ``read`` from it): built when not cached, brought up
        to date when another process has written a later revision. The caller holds the session's lock."""
        live = self._sessions.get(session_id, lambda: self._build(read or self.records.read(session_id)))
        if read is None:
            record = self.records.read_changed(session_id, live.record.revision)
        else:  # a live record newer than the caller's read is this process's own later edit
            record = read if read.revision > live.record.revision else None
        if record is not None:
            live.solver.sync({c.id: (*internal_paths(live.pair, c), c.spec.weight) for c in record.curves})
            live.record = record
            self.fit_energy(live)
        return live

    def _build(self, record: SessionRecord) -> LiveSession:
        need_M, need_N = basis_needs(record)
        meshes = self.mesh(record.source, "source"), self.mesh(record.target, "target")
        pair = ShapePair(*meshes, self.basis(need_M), self.basis(need_N))
        for mesh_id, mesh in ((record.source, pair.mesh_M), (record.target, pair.mesh_N)):
            mesh.edge_graph  # noqa: B018  (cached property: built here so the first trace answers at once)
            guide = self.guide(mesh_id)
            if guide is not None:  # and what a trace near the display copy reads
                guide.cells  # noqa: B018
                display_graph(mesh, guide)
        return LiveSession(record, pair, self._solver(record, pair), LRU(8), LRU(2))

    def fit_energy(self, live: LiveSession) -> None:
        """Rebuild the session's solver when its curves now call for the other energy (:func:`energy_solver`: a
        combined session's curves can show the pair strongly non-isometric, or stop doing so)."""
        if type(live.solver) is not energy_solver(live.record, live.pair):
            live.solver.close()
            live.solver = self._solver(live.record, live.pair)

    def _solver(self, record: SessionRecord, pair: ShapePair) -> CurveMapSolver:
        # an edit solves only the map the texture needs, on one thread: with the cores shared (other sessions,
        # or the browser in bench_ui_latency) that took the solve from 11-13 to 8 ms
        # the landmark prior's descriptor operators cost a pass over every vertex once per shape (1.4 s at 110k),
        # so shapes above prior_max_vertices go without it
        small = max(mesh.n_vertices for mesh in pair.meshes) <= self.prior_max_vertices
        solver = build_solver(
            record,
            pair,
            interactive=True,
            executor=self._executor,
            prior_executor=self._prior_executor if small else None,
            landmark_prior=small,
        )
        if isinstance(solver, CombinedMapSolver):
            solver.on_prior = partial(self._prior_landed, record.id)
        return solver

    def _prior_landed(self, session_id: str) -> None:
        live = self._sessions.peek(session_id)
        if live is not None:
            self.notify(session_id, {"kind": "prior", "revision": live.record.revision})


SessionNotify = Callable[[str, dict[str, Any]], None]
"""Told of a committed change of a session (its id, and an event: ``kind``, ``revision`` and details), so that the
pages showing it update (:mod:`curvefm.service.session_events`)."""


def _nobody(session_id: str, event: dict[str, Any]) -> None:
    """No one follows the sessions (the command line, the library)."""


def _solve_map(solver: CurveMapSolver) -> None:
    try:
        solver.C_MN  # noqa: B018  (a property: solves when the last edit left the map stale)
    except Exception as error:  # the next read solves it again and answers with the error
        log.warning("solving a session's map beside its write failed: %s", type(error).__name__)


def _lower_priority() -> None:
    """Run the calling thread at nice 10 (Linux schedules threads one by one; elsewhere nothing changes)."""
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 10)
    except (AttributeError, OSError):
        pass
