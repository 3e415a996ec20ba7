"""Geometric-morphometrics file formats: a session's correspondences out as landmark configurations (curve
endpoints, semilandmarks resampled along the curves, pseudo-landmarks carried by the pointwise map) in 3D Slicer's
markups (``.mrk.json``, ``.fcsv``), TPS, morphologika and geomorph's ``curveslide.csv``; Slicer markups in, snapped
to the nearest vertices, as curve pairs to seed a session.

* ``configuration``: :class:`Configuration`, corresponding landmarks on source and target, built from a session;
* ``writing``: the file writers;
* ``reading``: Slicer markups read (:class:`Markup`) and paired between two files (:func:`pair_markups`);
* ``seeding``: markups snapped to the meshes (with each point's distance) and made :class:`CurveSpec` s;
* ``project``: a collection's configuration, a specimen per member (:func:`project_configuration`).
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
from curvefm.morphometrics.project import (
    MemberShape,
    live_mapped,
    missing_curves,
    project_configuration,
    run_mapped,
    template_pseudo,
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
    COLLECTION_EXPORTS,
    EXPORTS,
    MARKUPS_SCHEMA,
    curveslide_csv,
    fcsv,
    markups_json,
    morphologika,
    pseudo_landmarks_csv,
    tps,
    write_export,
)

__all__ = [
    "COLLECTION_EXPORTS",
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
    "MemberShape",
    "SeededCurve",
    "Seeding",
    "SnappedPoint",
    "Tolerance",
    "check_limits",
    "curveslide_csv",
    "fcsv",
    "live_configuration",
    "live_mapped",
    "markups_json",
    "missing_curves",
    "morphologika",
    "pair_markups",
    "project_configuration",
    "pseudo_landmarks",
    "pseudo_landmarks_csv",
    "read_markups",
    "refined_configuration",
    "resample_path",
    "run_mapped",
    "seed_curves",
    "session_configuration",
    "template_pseudo",
    "tps",
    "write_export",
]
