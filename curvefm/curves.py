"""Curves on a mesh: tracing from user input, uniform resampling and the restriction operator.

A curve is a vertex path (internal ids, consecutive vertices share an edge). For the functional-map energy it
is resampled uniformly by arc length to ``s`` points; each sample lies on an edge of the path, so restricting a
per-vertex function to the curve is a sparse ``s x n`` matrix ``P`` with two barycentric weights per row.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp

from curvefm import registry
from curvefm.errors import CurvefmError
from curvefm.mesh import Mesh
from curvefm.paths import check_edge_path

DEFAULT_SAMPLES = 100


def trace_curve(
    mesh: Mesh,
    waypoints: Sequence[int] | None = None,
    path: Sequence[int] | None = None,
    tracer: str = "geodesic",
    params: dict | None = None,
) -> np.ndarray:
    """Return a vertex path (internal ids) from user input in **file** ids.

    Give either ``waypoints`` (two endpoints, or more points the curve must pass in order; consecutive
    points are joined by the tracer) or an explicit ``path`` (checked to be edge-connected).
    """
    if (waypoints is None) == (path is None):
        raise CurvefmError("give a curve either as waypoints (endpoints) or as an explicit vertex path")
    if path is not None:
        internal = mesh.internal_ids(path, "path vertex")
        check_edge_path(mesh.edge_graph, internal)
        return internal
    points = mesh.internal_ids(waypoints, "waypoint")
    if len(points) < 2:
        raise CurvefmError(f"a curve needs at least two waypoints (start and end), got {len(points)}")
    plugin = registry.get("tracer", tracer)
    parsed = plugin.parse_params(params)
    pieces = [plugin.run(mesh, int(a), int(b), parsed) for a, b in zip(points[:-1], points[1:], strict=True)]
    traced = np.concatenate([pieces[0]] + [p[1:] for p in pieces[1:]])
    if len(traced) < 2:
        raise CurvefmError("the curve's start and end are the same vertex; pick two different points")
    return traced


def resample(vertices: np.ndarray, path: np.ndarray, samples: int = DEFAULT_SAMPLES):
    """Uniform arc-length samples along a vertex path.

    Returns ``(a, b, t)``: sample ``r`` lies at ``(1 - t[r]) * vertices[a[r]] + t[r] * vertices[b[r]]``.
    """
    segment = np.linalg.norm(np.diff(vertices[path], axis=0), axis=1)
    cumulative = np.r_[0.0, np.cumsum(segment)]
    if cumulative[-1] <= 0:
        raise CurvefmError("the curve has zero length; pick two different points")
    positions = np.linspace(0.0, cumulative[-1], samples)
    index = np.clip(np.searchsorted(cumulative, positions, side="right") - 1, 0, len(segment) - 1)
    t = (positions - cumulative[index]) / np.maximum(segment[index], 1e-300)
    return path[index], path[index + 1], np.clip(t, 0.0, 1.0)


def restriction_operator(n_vertices: int, a: np.ndarray, b: np.ndarray, t: np.ndarray) -> sp.csr_matrix:
    """Sparse ``s x n`` matrix with barycentric weights: ``P @ f`` samples ``f`` along the curve."""
    rows = np.arange(len(a))
    return sp.csr_matrix(
        (np.r_[1.0 - t, t], (np.r_[rows, rows], np.r_[a, b])), shape=(len(a), n_vertices)
    )


def restrict(mesh_vertices: np.ndarray, path: np.ndarray, evecs: np.ndarray, samples: int) -> np.ndarray:
    """``P_gamma @ evecs`` for a curve: the basis restricted to ``samples`` uniform points (s x k)."""
    P = restriction_operator(len(evecs), *resample(mesh_vertices, path, samples))
    return P @ evecs
