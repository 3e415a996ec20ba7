"""Coarse copies of a mesh by quadric edge-collapse decimation (open3d), for work that needs the shape at a few
thousand vertices only: the multiresolution basis, and RHM on big meshes.
"""

from __future__ import annotations

import numpy as np


def decimate(vertices: np.ndarray, faces: np.ndarray, vertex_count: int) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, faces)`` of a copy with about ``vertex_count`` vertices (``2 * vertex_count`` triangles).
    The coarse vertices are new points near the surface, not a subset of the original ones."""
    import open3d as o3d  # about 2 s of CPU to import: only here, for big meshes

    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(vertices), o3d.utility.Vector3iVector(faces))
    coarse = mesh.simplify_quadric_decimation(target_number_of_triangles=2 * vertex_count)
    return np.asarray(coarse.vertices), np.asarray(coarse.triangles, dtype=np.int64)
