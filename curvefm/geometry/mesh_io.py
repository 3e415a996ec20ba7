"""Reading and writing mesh files, one module per format under :mod:`curvefm.geometry.formats`.

Every reader keeps the file's vertex order, so vertex ids a user reads off a file stay valid.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from curvefm.errors import InvalidInput, NotFound
from curvefm.geometry.formats.gltf import read_gltf
from curvefm.geometry.formats.obj import read_obj, write_obj
from curvefm.geometry.formats.off import read_off, write_off
from curvefm.geometry.formats.ply_stl import read_ply_stl, write_ply_stl
from curvefm.geometry.mesh import Mesh

OPEN3D_FORMATS = {".ply", ".stl"}
GLTF_FORMATS = {".glb", ".gltf"}
SUPPORTED_FORMATS = sorted(OPEN3D_FORMATS | GLTF_FORMATS | {".obj", ".off"})


def load_mesh(path: str | os.PathLike, name: str | None = None) -> Mesh:
    """Load a mesh, keeping the file's vertex order in every format.

    OBJ is read by our own parser because open3d's OBJ reader reorders vertices (by first use) and splits
    them at uv seams, which would silently break vertex ids and ground truth.
    """
    path = Path(path)
    name = name or path.stem
    suffix = path.suffix.lower()
    if not path.is_file():
        raise NotFound(f"mesh file not found: {path}")
    if suffix not in SUPPORTED_FORMATS:
        raise InvalidInput(
            f"unsupported mesh format '{suffix}' for {path.name}; supported: {', '.join(SUPPORTED_FORMATS)}"
        )
    if suffix == ".obj":
        return read_obj(path, name)
    if suffix == ".off":
        return read_off(path, name)
    if suffix in GLTF_FORMATS:
        return read_gltf(path, name)
    return read_ply_stl(path, name)


def save_mesh(mesh: Mesh, path: str | os.PathLike, uv: np.ndarray | None = None) -> None:
    """Write a mesh. OBJ is written by us (with ``uv`` or the mesh's own uv as ``vt``); other formats by open3d."""
    path = Path(path)
    suffix = path.suffix.lower()
    uv = mesh.uv if uv is None else uv
    if suffix == ".obj":
        write_obj(mesh, path, uv)
        return
    if suffix == ".off":
        write_off(mesh, path)
        return
    if suffix not in OPEN3D_FORMATS:
        raise InvalidInput(f"cannot write format '{suffix}'; supported: {', '.join(SUPPORTED_FORMATS)}")
    write_ply_stl(mesh, path)
