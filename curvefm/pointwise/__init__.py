"""Pointwise maps: conversion from functional maps (spectral nearest neighbours), the helpers the refining
converters share, the user's curves as constraints on them, intrinsic quality figures (no ground truth needed),
exact high-dimensional neighbour search, and geodesic embeddings for RHM.
"""

from curvefm.pointwise.conversion import (
    PointwiseMaps,
    fmap_from_pointwise,
    pointwise_from_both,
    pointwise_from_fmap,
)
from curvefm.pointwise.curve_pins import CurvePins, no_pins
from curvefm.pointwise.geodesic_mds import (
    biharmonic_extension,
    classical_mds,
    closest_on_triangles,
    closest_points,
    geodesic_embedding,
    smacof,
    vertex_faces,
)
from curvefm.pointwise.neighbors import BLOCK, nearest_neighbors
from curvefm.pointwise.quality import MapQuality, compare, measure
from curvefm.pointwise.refinement import bases_with, initial_maps, spread_samples, unit_area

__all__ = [
    "BLOCK",
    "CurvePins",
    "MapQuality",
    "PointwiseMaps",
    "bases_with",
    "biharmonic_extension",
    "classical_mds",
    "closest_on_triangles",
    "closest_points",
    "compare",
    "fmap_from_pointwise",
    "geodesic_embedding",
    "initial_maps",
    "measure",
    "nearest_neighbors",
    "no_pins",
    "pointwise_from_both",
    "pointwise_from_fmap",
    "smacof",
    "spread_samples",
    "unit_area",
    "vertex_faces",
]
