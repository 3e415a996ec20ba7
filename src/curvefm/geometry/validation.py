"""Building a :class:`Mesh` from raw arrays: every check a file or an upload must pass."""

from __future__ import annotations

import os
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike
from scipy.sparse.csgraph import connected_components

from curvefm.errors import InvalidInput, ResourceLimit
from curvefm.geometry.mesh import Mesh, MeshReport, edge_counts


def max_vertices() -> int:
    """Largest accepted vertex count (``CURVEFM_MAX_VERTICES``, default two million)."""
    return int(os.environ.get("CURVEFM_MAX_VERTICES", 2_000_000))


def check_vertex_count(n: int, what: str) -> None:
    """Refuse more than :func:`max_vertices` vertices; readers call it with a header's count before reading."""
    if n > max_vertices():
        raise ResourceLimit(
            f"{what} {n} vertices, more than the limit of {max_vertices()} "
            "(set CURVEFM_MAX_VERTICES to change it, or decimate the mesh)",
        )


# ----------------------------------------------------------------------------------------------------------
# Building and validating


def build_mesh(
    vertices: ArrayLike, faces: Any, uv: ArrayLike | None = None, *, name: str = "", texture_path: str | None = None
) -> Mesh:
    """Validate raw arrays and build a :class:`Mesh`.

    ``faces`` may be an (f, 3) array, a list of polygons or :class:`Polygons`; polygons with more than three corners are
    triangulated as fans (counted in the report). Faces with fewer than three corners, indices out of range,
    non-finite coordinates and empty meshes are rejected. Degenerate faces (a repeated corner or zero area)
    are removed, then vertices no face uses are dropped with their ids remembered in ``file_ids``.
    Non-manifold edges, boundaries and several components are reported, not fatal.
    """
    report = MeshReport()
    vertices = _checked_vertices(vertices, name)
    n_file = len(vertices)
    tris = _triangulate(faces, report, name)
    _check_indices(tris, n_file, name)
    tris = _drop_degenerate(vertices, tris, report, name)
    used = _used_vertices(tris, n_file)
    file_ids = used.astype(np.int64)
    if len(used) < n_file:
        report.unreferenced_vertices_removed = n_file - len(used)
        report.warnings.append(f"{n_file - len(used)} vertices belong to no face and were dropped; file ids stay valid")
        remap = np.full(n_file, -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        tris = remap[tris]
    if uv is not None:
        uv = np.asarray(uv, dtype=np.float64)[file_ids]
    mesh = Mesh(
        vertices=np.ascontiguousarray(vertices[file_ids]),
        faces=np.ascontiguousarray(tris, dtype=np.int64),
        file_ids=file_ids,
        n_file_vertices=n_file,
        report=report,
        uv=uv,
        texture_path=texture_path,
        name=name,
    )
    _note_topology(mesh, report)
    return mesh


def _checked_vertices(vertices: ArrayLike, name: str) -> np.ndarray:
    try:
        v = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInput(f"mesh '{name}': vertex coordinates are not numbers ({exc})") from None
    if v.size == 0:
        raise InvalidInput(f"mesh '{name}' is empty: it has no vertices")
    if v.ndim != 2 or v.shape[1] != 3:
        raise InvalidInput(f"mesh '{name}': vertices must be an (n, 3) array, got shape {v.shape}")
    check_vertex_count(len(v), f"mesh '{name}' has")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise InvalidInput(
            f"mesh '{name}' has {int(bad.sum())} vertices with non-finite coordinates (NaN or inf), "
            f"the first is vertex {int(np.flatnonzero(bad)[0])}"
        )
    return v


class Polygons(NamedTuple):
    """Faces of any sizes without a Python list per face: face ``i`` has ``sizes[i]`` corners, stored back to
    back in ``corners`` (vertex ids). Readers build one in a few bytes per corner."""

    corners: np.ndarray
    sizes: np.ndarray


def _triangulate(faces: Any, report: MeshReport, name: str) -> np.ndarray:
    shaped = _as_triangles_or_polygons(faces)
    tris = _fan_triangles(shaped, report, name) if isinstance(shaped, Polygons) else shaped
    if len(tris) == 0:
        raise InvalidInput(f"mesh '{name}' has no faces; only triangle (or polygon) meshes are supported")
    if not np.issubdtype(tris.dtype, np.integer):
        raise InvalidInput(f"mesh '{name}': face indices must be integers")
    if report.triangulated_polygons:
        report.warnings.append(f"{report.triangulated_polygons} polygons were triangulated as fans")
    return tris.astype(np.int64, copy=False)


def _as_triangles_or_polygons(faces: Any) -> np.ndarray | Polygons:
    if isinstance(faces, Polygons):
        return faces
    if isinstance(faces, np.ndarray) and faces.ndim == 2:
        return faces if faces.shape[1] == 3 else Polygons(faces.ravel(), np.full(len(faces), faces.shape[1]))
    faces = [list(f) for f in faces] if faces is not None else []
    if all(len(f) == 3 for f in faces):
        return np.array(faces).reshape(-1, 3)
    return Polygons(np.array([i for f in faces for i in f]), np.array([len(f) for f in faces], dtype=np.int64))


def _fan_triangles(polygons: Polygons, report: MeshReport, name: str) -> np.ndarray:
    """Polygon ``[c0, c1, ..., ck]`` becomes triangles ``[c0, ci, ci+1]``, in order, without a Python loop."""
    corners, sizes = polygons
    short = np.flatnonzero(sizes < 3)
    if len(short):
        raise InvalidInput(
            f"mesh '{name}': face {short[0]} has {sizes[short[0]]} corners; faces need at least 3 "
            "(lines and points are not surfaces)"
        )
    report.triangulated_polygons = int((sizes > 3).sum())
    if not report.triangulated_polygons:
        return corners.reshape(-1, 3)
    per_face = sizes - 2
    first = np.repeat(np.cumsum(sizes) - sizes, per_face)  # offset of each triangle's polygon in corners
    step = np.arange(len(first)) - np.repeat(np.cumsum(per_face) - per_face, per_face) + 1
    return np.column_stack([corners[first], corners[first + step], corners[first + step + 1]])


def _check_indices(tris: np.ndarray, n: int, name: str) -> None:
    bad = (tris < 0) | (tris >= n)
    if bad.any():
        face = int(np.flatnonzero(bad.any(axis=1))[0])
        raise InvalidInput(
            f"mesh '{name}': face {face} refers to vertex {int(tris[bad][0])}, but the mesh has {n} vertices "
            f"(valid ids are 0..{n - 1})"
        )


DEGENERATE_CHECK_FACES = 1 << 16
"""Faces whose areas are computed at once: a whole big mesh's corner coordinates would be 72 bytes a face."""


def _drop_degenerate(vertices: np.ndarray, tris: np.ndarray, report: MeshReport, name: str) -> np.ndarray:
    repeated = (tris[:, 0] == tris[:, 1]) | (tris[:, 1] == tris[:, 2]) | (tris[:, 0] == tris[:, 2])
    scale = np.ptp(vertices, axis=0).max() if len(vertices) > 1 else 1.0
    smallest = 1e-14 * max(scale, 1e-300) ** 2
    flat = np.concatenate(
        [
            _doubled_areas(vertices, tris[start : start + DEGENERATE_CHECK_FACES]) <= smallest
            for start in range(0, len(tris), DEGENERATE_CHECK_FACES)
        ]
    )
    degenerate = repeated | flat
    if degenerate.all():
        raise InvalidInput(f"mesh '{name}': all {len(tris)} faces are degenerate (zero area)")
    if degenerate.any():
        report.degenerate_faces_removed = int(degenerate.sum())
        report.warnings.append(f"{int(degenerate.sum())} degenerate faces (zero area) were removed")
        return tris[~degenerate]
    return tris


def _doubled_areas(vertices: np.ndarray, tris: np.ndarray) -> np.ndarray:
    p0 = vertices[tris[:, 0]]
    areas: np.ndarray = np.linalg.norm(np.cross(vertices[tris[:, 1]] - p0, vertices[tris[:, 2]] - p0), axis=1)
    return areas


def _used_vertices(tris: np.ndarray, n: int) -> np.ndarray:
    """The sorted ids of the vertices some face uses (a mask of ``n`` bytes, not a sorted copy of the faces)."""
    used = np.zeros(n, dtype=bool)
    used[tris.ravel()] = True
    return np.flatnonzero(used)


def _note_topology(mesh: Mesh, report: MeshReport) -> None:
    counts = edge_counts(mesh.faces, mesh.n_vertices)
    report.non_manifold_edges = int((counts > 2).sum())
    report.boundary_edges = int((counts == 1).sum())
    report.components = _components(mesh.faces, mesh.n_vertices)
    if report.non_manifold_edges:
        report.warnings.append(f"{report.non_manifold_edges} non-manifold edges (shared by 3+ faces)")
    if report.components > 1:
        report.warnings.append(f"{report.components} connected components: curves cannot cross between components")


def _components(faces: np.ndarray, n: int) -> int:
    """Connected components of the faces' vertices: two edges per face join its corners (an unweighted graph
    with 32-bit ids, a fraction of the size of the mesh's edge-length graph)."""
    rows = np.concatenate([faces[:, 0], faces[:, 1]]).astype(np.int32)
    cols = np.concatenate([faces[:, 1], faces[:, 2]]).astype(np.int32)
    graph = sp.csr_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(n, n))
    return int(connected_components(graph, directed=False)[0])


def per_vertex_uv(faces: np.ndarray, corner_uv: np.ndarray, n: int) -> np.ndarray:
    """One uv per vertex from per-corner uvs; at a seam the first corner's value wins."""
    uv = np.full((n, 2), np.nan)
    flat_ids = faces.reshape(-1)[::-1]
    uv[flat_ids] = corner_uv.reshape(-1, 2)[::-1]  # reversed so the first occurrence is written last
    filled: np.ndarray = np.nan_to_num(uv)
    return filled
