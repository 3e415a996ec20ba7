"""Pointwise maps: conversion from functional maps (spectral nearest neighbours), the helpers the refining
converters share, the user's curves as constraints on them, intrinsic quality figures (no ground truth needed),
high-dimensional neighbour search (exact or approximate), refinement on vertex samples, and geodesic
embeddings for RHM.

Building blocks (the MDS steps of :mod:`~curvefm.pointwise.geodesic_mds`, the search's block size) are imported
from their modules; the search and sampling thresholds that the converters' parameters show stay exported.
"""

from curvefm.pointwise.conversion import (
    PointwiseMaps,
    fmap_from_pointwise,
    nearest_orthogonal,
    orthogonal_steps,
    pointwise_from_both,
    pointwise_from_fmap,
    room_for_steps,
    stepped_size,
)
from curvefm.pointwise.curve_pins import CurvePins, no_pins
from curvefm.pointwise.geodesic_mds import (
    closest_points,
    geodesic_embedding,
)
from curvefm.pointwise.neighbors import (
    APPROXIMATE_FROM_PAIRS,
    Search,
    nearest_neighbors,
    uses_approximate,
)
from curvefm.pointwise.quality import MapQuality, compare, edge_stretch, measure
from curvefm.pointwise.refinement import bases_with, initial_maps, unit_area
from curvefm.pointwise.sampled import (
    AUTO_SAMPLES,
    DENSE_UP_TO,
    STEP_SAMPLES,
    VertexRows,
    area_samples,
    fit_fmap,
    match_rows,
    refinement_samples,
    sampled_orthogonal_steps,
)
from curvefm.pointwise.suggestion import SuggestedCurve, suggest_curve

__all__ = [
    "APPROXIMATE_FROM_PAIRS",
    "AUTO_SAMPLES",
    "DENSE_UP_TO",
    "STEP_SAMPLES",
    "Search",
    "SuggestedCurve",
    "VertexRows",
    "CurvePins",
    "MapQuality",
    "PointwiseMaps",
    "area_samples",
    "bases_with",
    "closest_points",
    "compare",
    "edge_stretch",
    "fit_fmap",
    "fmap_from_pointwise",
    "geodesic_embedding",
    "initial_maps",
    "match_rows",
    "measure",
    "nearest_neighbors",
    "nearest_orthogonal",
    "no_pins",
    "room_for_steps",
    "orthogonal_steps",
    "pointwise_from_both",
    "pointwise_from_fmap",
    "refinement_samples",
    "sampled_orthogonal_steps",
    "stepped_size",
    "suggest_curve",
    "unit_area",
    "uses_approximate",
]
