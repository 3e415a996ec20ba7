"""Reading and writing mesh files, one module per format under :mod:`curvefm.geometry.formats`.

Every reader keeps the file's vertex order, so vertex ids a user reads off a file stay valid.
"""

from __future__ import annotations

import os
import tempfile
import zipfile
from pathlib import Path
from typing import BinaryIO

import numpy as np

from curvefm.errors import InvalidInput, NotFound
from curvefm.geometry.formats.gltf import read_gltf
from curvefm.geometry.formats.obj import read_obj, write_obj
from curvefm.geometry.formats.off import read_off, write_off
from curvefm.geometry.formats.ply import read_ply
from curvefm.geometry.formats.ply_stl import write_ply_stl
from curvefm.geometry.formats.stl import read_stl
from curvefm.geometry.mesh import Mesh
from curvefm.geometry.texture import checkerboard_image

OPEN3D_FORMATS = {".ply", ".stl"}
"""Formats open3d writes; every format is read by our own code or trimesh."""
GLTF_FORMATS = {".glb", ".gltf"}
ZIP_LEVEL = 1
"""Deflate level of the textured zip: the 440k target's 75 MB OBJ in 4.2 s and 21 MB at 1, 18.8 s and 17 MB at
zlib's default 6 (2026-11-28, loaded)."""
SUPPORTED_FORMATS = sorted(OPEN3D_FORMATS | GLTF_FORMATS | {".obj", ".off"})
READERS = {
    ".obj": read_obj,
    ".off": read_off,
    ".ply": read_ply,
    ".stl": read_stl,
    ".glb": read_gltf,
    ".gltf": read_gltf,
}


def load_mesh(path: str | os.PathLike[str], name: str | None = None) -> Mesh:
    """Load a mesh, keeping the file's vertex order in every format.

    Every reader checks what a header declares against the file's size before allocating for it, streams
    or views the file so that memory stays a small multiple of its size, and answers a malformed file with a
    :class:`CurvefmError` naming the file and, for text, the line. OBJ, OFF, PLY and STL are read by our own
    parsers (open3d's reorders OBJ vertices and allocates whatever a PLY or STL header declares); glTF by
    trimesh, self-contained files only.
    """
    path = Path(path)
    name = name or path.stem
    suffix = path.suffix.lower()
    if not path.is_file():
        raise NotFound(f"mesh file not found: {path}")
    if suffix not in READERS:
        raise InvalidInput(
            f"unsupported mesh format '{suffix}' for {path.name}; supported: {', '.join(SUPPORTED_FORMATS)}"
        )
    if path.stat().st_size == 0:
        raise InvalidInput(f"could not read any vertices from {path.name}: the file is empty")
    return READERS[suffix](path, name)


def save_mesh(mesh: Mesh, path: str | os.PathLike[str], uv: np.ndarray | None = None) -> None:
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


def save_textured_zip(mesh: Mesh, uv: np.ndarray, out: str | os.PathLike[str] | BinaryIO, stem: str) -> None:
    """The mesh with texture coordinates ``uv`` as ``<stem>.obj``, its material ``<stem>.mtl`` and texture image
    ``<stem>.png`` (the web UI's checkerboard) in one zip file, which 3D tools open as a textured mesh."""
    with tempfile.TemporaryDirectory(prefix="curvefm-textured-") as folder:
        zip_files(save_textured(mesh, uv, folder, stem), out)


def save_textured(mesh: Mesh, uv: np.ndarray, folder: str | os.PathLike[str], stem: str) -> list[Path]:
    """``<stem>.obj`` (with ``uv`` and ``mtllib``/``usemtl``), ``<stem>.mtl`` and ``<stem>.png`` (the web UI's
    checkerboard) in ``folder``: a textured mesh for 3D tools. Returns the three paths."""
    from PIL import Image  # only this export needs it

    files = [Path(folder) / f"{stem}{suffix}" for suffix in (".obj", ".mtl", ".png")]
    write_obj(mesh, files[0], uv, material=stem)
    files[1].write_text(f"newmtl {stem}\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nillum 1\nmap_Kd {stem}.png\n")
    Image.fromarray(checkerboard_image()).save(files[2])
    return files


def zip_files(files: list[Path], out: str | os.PathLike[str] | BinaryIO) -> None:
    """``files`` under their own names in one deflated zip file (:data:`ZIP_LEVEL`)."""
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED, compresslevel=ZIP_LEVEL) as archive:
        for path in files:
            archive.write(path, path.name)
