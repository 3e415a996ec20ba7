"""The session domain shared by the service and the workers: curve specs in file ids and their tracing, the
persisted session record, and the shape pair with its bases from which a session's solver is rebuilt.
"""

from curvefm.session.curves import CurvesFile, CurveSpec, read_curves, trace_curve, trace_pair
from curvefm.session.pair import (
    basis_available,
    build_solver,
    internal_paths,
    load_basis,
    load_pair,
    missing_basis_error,
)
from curvefm.session.record import CurveRecord, SessionRecord
from curvefm.spectral import ShapePair  # defined below the maps that use it; the session's pair is the same type

__all__ = [
    "CurveRecord",
    "CurveSpec",
    "CurvesFile",
    "SessionRecord",
    "ShapePair",
    "basis_available",
    "build_solver",
    "internal_paths",
    "load_basis",
    "load_pair",
    "missing_basis_error",
    "read_curves",
    "trace_curve",
    "trace_pair",
]
