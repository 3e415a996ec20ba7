"""Geometric-morphometrics file formats: a session's correspondences out as landmark configurations (curve
endpoints, semilandmarks resampled along the curves, pseudo-landmarks carried by the pointwise map) in 3D Slicer's
markups (``.mrk.json``, ``.fcsv``), TPS, morphologika and geomorph's ``curveslide.csv``; Slicer markups in, snapped
to the nearest vertices, as curve pairs to seed a session.

* ``configuration``: :class:`Configuration`, corresponding landmarks on source and target, built from a session;
* ``writing``: the file writers;
* ``reading``: Slicer markups read (:class:`Markup`) and paired between two files (:func:`pair_markups`);
* ``seeding``: markups snapped to the meshes (with each point's distance) and made :class:`CurveSpec` s.
"""

from curvefm.morphometrics.configuration import (
    DEFAULT_SEMILANDMARKS,
    MAX_PSEUDO_LANDMARKS,
    MAX_SEMILANDMARKS,
    Configuration,
    CurveLandmarks,
    live_configuration,
    pseudo_landmarks,
    refined_configuration,
    resample_path,
    session_configuration,
)
from curvefm.morphometrics.reading import Markup, MarkupPairs, pair_markups, read_markups
from curvefm.morphometrics.seeding import (
    DEFAULT_SNAP_TOLERANCE,
    SeededCurve,
    Seeding,
    SnappedPoint,
    Tolerance,
    check_limits,
    seed_curves,
)
from curvefm.morphometrics.writing import (
    EXPORTS,
    MARKUPS_SCHEMA,
    curveslide_csv,
    fcsv,
    markups_json,
    morphologika,
    tps,
    write_export,
)

__all__ = [
    "DEFAULT_SEMILANDMARKS",
    "DEFAULT_SNAP_TOLERANCE",
    "EXPORTS",
    "MARKUPS_SCHEMA",
    "MAX_PSEUDO_LANDMARKS",
    "MAX_SEMILANDMARKS",
    "Configuration",
    "CurveLandmarks",
    "Markup",
    "MarkupPairs",
    "SeededCurve",
    "Seeding",
    "SnappedPoint",
    "Tolerance",
    "check_limits",
    "curveslide_csv",
    "fcsv",
    "live_configuration",
    "markups_json",
    "morphologika",
    "pair_markups",
    "pseudo_landmarks",
    "read_markups",
    "refined_configuration",
    "resample_path",
    "seed_curves",
    "session_configuration",
    "tps",
    "write_export",
]
