"""Pointwise maps: conversion from functional maps (spectral nearest neighbours), the helpers the refining
converters share, exact high-dimensional neighbour search, and geodesic embeddings for RHM.
"""

from curvefm.pointwise.conversion import (
    PointwiseMaps,
    fmap_from_pointwise,
    pointwise_from_both,
    pointwise_from_fmap,
)
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
from curvefm.pointwise.refinement import bases_with, initial_maps, spread_samples, unit_area

__all__ = [
    "BLOCK",
    "PointwiseMaps",
    "bases_with",
    "biharmonic_extension",
    "classical_mds",
    "closest_on_triangles",
    "closest_points",
    "fmap_from_pointwise",
    "geodesic_embedding",
    "initial_maps",
    "nearest_neighbors",
    "pointwise_from_both",
    "pointwise_from_fmap",
    "smacof",
    "spread_samples",
    "unit_area",
    "vertex_faces",
]
