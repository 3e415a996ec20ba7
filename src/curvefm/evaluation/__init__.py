"""Measuring maps against ground truth: geodesic error metrics, the shared data sets' ground-truth readers,
the curves-from-ground-truth protocol of the tests and benchmarks, and ``curvefm reproduce``.
"""

from curvefm.evaluation.ground_truth import (
    GroundTruth,
    cat_lion_truth,
    faust5k_truth,
    file_pairs_truth,
    ground_truth_for,
    identity_truth,
    read_lion2cat,
    read_pid,
    read_vts,
    shared_data_dir,
    tosca_class,
    tosca_landmark_truth,
)
from curvefm.evaluation.metrics import ErrorSummary, evaluate_map, map_geodesic_errors
from curvefm.evaluation.protocol import (
    ENDPOINT_SIDES,
    CurvePool,
    carried_path,
    evaluate_pair,
    ground_truth_curves,
    reversed_truth,
    score,
    score_maps,
    truth_away_from_ends,
    truth_to_score,
)

__all__ = [
    "ENDPOINT_SIDES",
    "CurvePool",
    "ErrorSummary",
    "GroundTruth",
    "carried_path",
    "cat_lion_truth",
    "evaluate_map",
    "evaluate_pair",
    "faust5k_truth",
    "file_pairs_truth",
    "ground_truth_curves",
    "ground_truth_for",
    "identity_truth",
    "map_geodesic_errors",
    "read_lion2cat",
    "read_pid",
    "read_vts",
    "reversed_truth",
    "score",
    "score_maps",
    "shared_data_dir",
    "tosca_class",
    "tosca_landmark_truth",
    "truth_away_from_ends",
    "truth_to_score",
]
