"""PLY and STL through open3d (both round-trip vertex order exactly; STL has no vertex ids).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from curvefm.errors import InvalidInput
from curvefm.geometry.mesh import Mesh
from curvefm.geometry.validation import build_mesh, per_vertex_uv


def read_ply_stl(path: Path, name: str) -> Mesh:
    import open3d as o3d

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    m = o3d.io.read_triangle_mesh(str(path), enable_post_processing=False)
    vertices = np.asarray(m.vertices)
    faces = np.asarray(m.triangles)
    if len(vertices) == 0:
        raise InvalidInput(f"could not read any vertices from {path.name}: the file is empty or malformed")
    if len(faces) == 0:
        raise InvalidInput(f"{path.name} has no faces; only triangle meshes are supported")
    uv = None
    if m.has_triangle_uvs():
        uv = per_vertex_uv(faces, np.asarray(m.triangle_uvs).reshape(-1, 3, 2), len(vertices))
    if path.suffix.lower() == ".stl":
        vertices, faces = _weld(vertices, faces)
    return build_mesh(vertices, faces, uv, name=name)


def _weld(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """STL stores every triangle's corners separately and no vertex ids: merge equal positions, numbering
    vertices in order of first appearance in the file (the only order an STL file defines)."""
    unique, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return unique[order], rank[inverse.ravel()][faces]


def write_ply_stl(mesh: Mesh, path: Path) -> None:
    import open3d as o3d

    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(mesh.vertices), o3d.utility.Vector3iVector(mesh.faces))
    if path.suffix.lower() == ".stl":
        m.compute_triangle_normals()  # open3d refuses to write STL without normals
    if not o3d.io.write_triangle_mesh(str(path), m):
        raise InvalidInput(f"could not write {path.name}")
