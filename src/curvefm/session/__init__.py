"""The session domain, shared by the service and the workers: a shape pair, the solver's parameters and the
curves a user draws, kept as a record on disk and, in a long-running process, live in memory.

* ``curves``: curve specs in file vertex ids and tracing them into vertex paths;
* ``record``: the persisted :class:`SessionRecord` (and :class:`SessionCreate`, what a new one is made of;
  both validate ``k``, ``alpha`` and ``samples`` with the same types);
* ``restore``: a session restored from the store: its :class:`ShapePair` (:mod:`curvefm.spectral`'s) and its solver
  rebuilt from a record (:func:`build_solver`; its curve ids are the record's);
* ``live``: :class:`LiveSessions`, the bounded in-memory cache of solvers, shapes, bases and transfers, with a
  fixed set of locks;
* ``editing``: :class:`SessionEditor`, the operations (create, add / replace / remove a curve, maps,
  transfer, the maps' round-trip quality), each edit written to disk before it returns;
* :class:`SessionLimits` (from :mod:`curvefm.limits`, outside the package so that the command line reads the
  ``serve`` options without importing the session domain): the configurable bounds on what one request may ask
  (waypoints, path vertices, curves, ``k``).
"""

from curvefm.limits import SessionLimits
from curvefm.session.curves import (
    EXAMPLE_PATHS,
    MAX_VERTEX_ID,
    CurvesFile,
    CurveSpec,
    CurveWeight,
    VertexId,
    pinned_pieces,
    read_curves,
    trace_curve,
    trace_pair,
)
from curvefm.session.editing import (
    CurveSuggestion,
    MapQuality,
    MapSummary,
    SessionEditor,
    SolveStatement,
    StatedMaps,
    TransferFunction,
    Transferred,
    check_revision,
    source_function,
)
from curvefm.session.live import (
    DEFAULT_LOCK_TIMEOUT_S,
    LiveSession,
    LiveSessions,
    SessionBusy,
    SessionNotify,
    UnknownShape,
)
from curvefm.session.record import (
    NAME_LENGTH,
    SHARING_DESCRIPTION,
    Alpha,
    CurveRecord,
    MapSize,
    Samples,
    SessionCreate,
    SessionRecord,
    Sharing,
    UnknownSession,
    VertexPath,
)
from curvefm.session.restore import (
    BasisNeed,
    MissingBasis,
    basis_available,
    basis_needs,
    build_solver,
    internal_paths,
    load_basis,
    load_pair,
    stated_solve,
)

__all__ = [
    "DEFAULT_LOCK_TIMEOUT_S",
    "EXAMPLE_PATHS",
    "MAX_VERTEX_ID",
    "NAME_LENGTH",
    "SHARING_DESCRIPTION",
    "Alpha",
    "BasisNeed",
    "CurveRecord",
    "CurveSpec",
    "CurveWeight",
    "CurvesFile",
    "LiveSession",
    "LiveSessions",
    "MapQuality",
    "CurveSuggestion",
    "MapSize",
    "MapSummary",
    "MissingBasis",
    "Samples",
    "SessionCreate",
    "SessionEditor",
    "SessionLimits",
    "SessionRecord",
    "SessionBusy",
    "SessionNotify",
    "SolveStatement",
    "StatedMaps",
    "Sharing",
    "TransferFunction",
    "Transferred",
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
    "pinned_pieces",
    "read_curves",
    "source_function",
    "check_revision",
    "stated_solve",
    "trace_curve",
    "trace_pair",
]
