"""Writing PLY and STL through open3d; both are read by our own code (:mod:`.ply`, :mod:`.stl`)."""

from __future__ import annotations

from pathlib import Path

from curvefm.errors import InvalidInput
from curvefm.geometry.mesh import Mesh


def write_ply_stl(mesh: Mesh, path: Path) -> None:
    import open3d as o3d

    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(mesh.vertices), o3d.utility.Vector3iVector(mesh.faces))
    if path.suffix.lower() == ".stl":
        m.compute_triangle_normals()  # open3d refuses to write STL without normals
    if not o3d.io.write_triangle_mesh(str(path), m):
        raise InvalidInput(f"could not write {path.name}")
