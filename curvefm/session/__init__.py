"""The session domain, shared by the service and the workers: a shape pair, the solver's parameters and the
curves a user draws, kept as a record on disk and, in a long-running process, live in memory.

* ``curves``: curve specs in file vertex ids and tracing them into vertex paths;
* ``record``: the persisted :class:`SessionRecord` (and :class:`SessionCreate`, what a new one is made of;
  both validate ``k``, ``alpha`` and ``samples`` with the same types);
* ``record_store``: :class:`SessionStore`, records read and written atomically under ``<data>/sessions/``,
  with a revision number per write, and the refinement jobs run from each session;
* ``pair``: the :class:`ShapePair` (:mod:`curvefm.spectral`'s) loaded from the store, and the session's solver
  rebuilt from a record (:func:`build_solver`; its curve ids are the record's);
* ``live``: :class:`LiveSessions`, the bounded in-memory cache of solvers, shapes, bases and transfers, with a
  fixed set of locks;
* ``editing``: :class:`SessionEditor`, the operations (create, add / replace / remove a curve, maps,
  transfer, the maps' round-trip quality), each edit written to disk before it returns;
* ``limits``: :class:`SessionLimits`, the configurable bounds on what one request may ask (waypoints, path
  vertices, curves, ``k``).
"""

from curvefm.session.curves import (
    MAX_VERTEX_ID,
    CurvesFile,
    CurveSpec,
    VertexId,
    read_curves,
    trace_curve,
    trace_pair,
)
from curvefm.session.editing import MapQuality, MapSummary, SessionEditor, TransferFunction, source_function
from curvefm.session.limits import SessionLimits
from curvefm.session.live import LiveSession, LiveSessions, UnknownShape
from curvefm.session.pair import (
    BasisNeed,
    MissingBasis,
    basis_available,
    basis_needs,
    build_solver,
    internal_paths,
    load_basis,
    load_pair,
)
from curvefm.session.record import (
    SHARING_DESCRIPTION,
    Alpha,
    CurveRecord,
    MapSize,
    Samples,
    SessionCreate,
    SessionRecord,
    Sharing,
    VertexPath,
)
from curvefm.session.record_store import (
    DEFAULT_LOCK_TIMEOUT_S,
    RecordBusy,
    RecordFiles,
    SessionBusy,
    SessionStore,
    UnknownSession,
)
from curvefm.spectral import ShapePair  # defined below the maps that use it; the session's pair is the same type

__all__ = [
    "DEFAULT_LOCK_TIMEOUT_S",
    "MAX_VERTEX_ID",
    "SHARING_DESCRIPTION",
    "Alpha",
    "BasisNeed",
    "CurveRecord",
    "CurveSpec",
    "CurvesFile",
    "LiveSession",
    "LiveSessions",
    "MapQuality",
    "MapSize",
    "MapSummary",
    "MissingBasis",
    "Samples",
    "RecordBusy",
    "RecordFiles",
    "SessionCreate",
    "SessionEditor",
    "SessionLimits",
    "SessionRecord",
    "SessionBusy",
    "SessionStore",
    "ShapePair",
    "Sharing",
    "TransferFunction",
    "UnknownSession",
    "UnknownShape",
    "VertexId",
    "VertexPath",
    "basis_available",
    "basis_needs",
    "build_solver",
    "internal_paths",
    "load_basis",
    "load_pair",
    "read_curves",
    "source_function",
    "trace_curve",
    "trace_pair",
]
