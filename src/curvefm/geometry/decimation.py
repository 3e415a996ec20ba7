"""Coarse copies of a mesh by quadric edge-collapse decimation, for work that needs the shape at a few thousand
vertices only (the multiresolution basis, RHM and display copies of big meshes), and the interpolation weights
that carry functions on a coarse copy back to the full mesh.

Two decimators: open3d's (:func:`decimate`, RHM's and the display copies') and Fast-Quadric-Mesh-Simplification
(:func:`fast_decimate`, the multiresolution basis's). On FAUST subdivided once / twice (27,554 / 110,210
vertices) down to 8,000 vertices the second took 0.2 / 2.1 s against open3d's 3.4 / 8.1 s (2026-11-28, a loaded
machine), and with its aggressiveness at 2 (it grows its error threshold that slowly) the basis refined from it
had about the eigenvalue errors of open3d's (docs/performance.md); its default aggressiveness (7) made them 60x
larger.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

# chosen in docs/decisions.md#eigensolver
# Tried in turn until the copy has at most FAST_SLACK x the vertices asked for: the smaller, the closer to a true
# least-error-first decimation, but its error threshold stops growing after 100 passes, often short of the count
FAST_AGGRESSIVENESS = (2.0, 3.0, 7.0)  # 7, the library's default: eigenvalue errors 60x those of 2 on FAUST
FAST_SLACK = 1.25


def decimate(vertices: np.ndarray, faces: np.ndarray, vertex_count: int) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, faces)`` of a copy with about ``vertex_count`` vertices (``2 * vertex_count`` triangles).
    The coarse vertices are new points near the surface, not a subset of the original ones."""
    import open3d as o3d  # about 2 s of CPU to import: only here, for big meshes

    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(vertices), o3d.utility.Vector3iVector(faces))
    coarse = mesh.simplify_quadric_decimation(target_number_of_triangles=2 * vertex_count)
    return np.asarray(coarse.vertices), np.asarray(coarse.triangles, dtype=np.int64)


def fast_decimate(vertices: np.ndarray, faces: np.ndarray, vertex_count: int) -> tuple[np.ndarray, np.ndarray]:
    """As :func:`decimate`, by Fast-Quadric-Mesh-Simplification (several times faster than open3d's)."""
    import fast_simplification

    for aggressiveness in FAST_AGGRESSIVENESS:
        points, triangles = fast_simplification.simplify(
            vertices, faces, target_count=2 * vertex_count, agg=aggressiveness
        )
        if len(points) <= FAST_SLACK * vertex_count:
            break
    return np.asarray(points, dtype=np.float64), np.asarray(triangles, dtype=np.int64)


def closest_point_weights(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """``W`` (len(points) x len(vertices)): row i holds the barycentric weights of the point of the mesh
    ``(vertices, faces)`` closest to ``points[i]`` (three a row, summing to 1), so ``W @ f`` carries a function
    ``f`` on the mesh's vertices to the points by linear interpolation."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(vertices.astype(np.float32)), o3d.core.Tensor(faces.astype(np.uint32)))
    closest = scene.compute_closest_points(o3d.core.Tensor(points.astype(np.float32)))
    corners = faces[closest["primitive_ids"].numpy().astype(np.int64)]
    u, v = closest["primitive_uvs"].numpy().astype(float).T
    weights = np.clip(np.stack([1.0 - u - v, u, v], axis=1), 0.0, 1.0)
    weights /= weights.sum(axis=1, keepdims=True)
    rows = np.repeat(np.arange(len(points)), 3)
    return sp.csr_matrix((weights.ravel(), (rows, corners.ravel())), shape=(len(points), len(vertices)))
