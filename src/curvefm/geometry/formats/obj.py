"""Wavefront OBJ, read by our own parser: open3d's reorders vertices (by first use) and splits them at
uv seams, which would silently break vertex ids and ground truth.

Reading streams the file line by line into typed arrays (a few bytes per number), so memory stays a small
multiple of the file's size. What is read: ``v`` (the first three numbers; colours after them are ignored),
``vt`` (``u`` alone means ``v = 0``, as the OBJ format allows; a third value is ignored), ``f`` (1-based ids,
negative ids count back from the latest vertex, ``v/vt/vn`` corners) and ``mtllib``. Other statements are
ignored. ``mtllib`` and the ``map_Kd`` image it names are only opened inside the mesh's folder: an absolute
path or one with ``..`` is never opened, and the mesh then has no texture.
"""

from __future__ import annotations

from array import array
from pathlib import Path, PurePath

import numpy as np

from curvefm.errors import InvalidInput
from curvefm.geometry.formats.reading import TextLines, line_errors, numbers
from curvefm.geometry.mesh import Mesh
from curvefm.geometry.validation import Polygons, build_mesh, check_vertex_count, max_vertices, per_vertex_uv


def read_obj(path: Path, name: str) -> Mesh:
    parser = _ObjParser()
    with open(path, "rb") as f:
        lines = TextLines(f, path, "OBJ")
        with line_errors(lines):
            for tokens in lines:
                parser.statement(tokens)
    if not parser.vertices:
        raise InvalidInput(f"could not read any vertices from {path.name}: it has no vertex ('v') lines")
    vertices, faces = parser.mesh_arrays(path)
    uv = parser.vertex_uv(path, len(vertices))
    texture = _texture_from_mtl(path.parent, parser.mtllib)
    return build_mesh(vertices, faces, uv, name=name, texture_path=texture)


class _ObjParser:
    """The statements of one OBJ file, gathered into typed arrays as they come."""

    def __init__(self) -> None:
        self.vertices, self.texcoords = array("d"), array("d")
        self.corners, self.uv_corners, self.sizes = array("q"), array("q"), array("q")
        self.uv_complete = True  # every face gives a vt per corner; otherwise the file's uv are not used
        self.mtllib: bytes | None = None
        self.limit = 3 * max_vertices()

    def statement(self, tokens: list[bytes]) -> None:
        handler = self.HANDLERS.get(tokens[0])
        if handler:
            handler(self, tokens[1:])

    def vertex(self, values: list[bytes]) -> None:
        if len(values) < 3:
            raise ValueError(f"a vertex ('v') needs three coordinates, this one has {len(values)}")
        self.vertices.extend(numbers(values[:3]))
        if len(self.vertices) > self.limit:
            check_vertex_count(len(self.vertices) // 3, "this OBJ file has at least")

    def texcoord(self, values: list[bytes]) -> None:
        if not values:
            raise ValueError("a texture coordinate ('vt') needs at least one value")
        uv = numbers(values[:2])
        self.texcoords.extend(uv if len(uv) == 2 else (uv[0], 0.0))

    def face(self, corners: list[bytes]) -> None:
        if len(corners) < 3:
            raise ValueError(f"a face ('f') has {len(corners)} corners; faces need at least 3")
        ids = [corner.split(b"/") for corner in corners]
        n_vertices, n_texcoords = len(self.vertices) // 3, len(self.texcoords) // 2
        self.corners.extend([_index(c[0], n_vertices, "vertex") for c in ids])
        self.sizes.append(len(ids))
        self.uv_complete = self.uv_complete and all(len(c) > 1 and c[1] for c in ids)
        if self.uv_complete:
            self.uv_corners.extend([_index(c[1], n_texcoords, "texture coordinate") for c in ids])

    def mtl(self, names: list[bytes]) -> None:
        self.mtllib = b" ".join(names)

    HANDLERS = {b"v": vertex, b"vt": texcoord, b"f": face, b"mtllib": mtl}

    def mesh_arrays(self, path: Path) -> tuple[np.ndarray, Polygons]:
        vertices = np.frombuffer(self.vertices, dtype=np.float64).reshape(-1, 3)
        corners = _in_range(self.corners, len(vertices), "vertex", path)
        return vertices, Polygons(corners, np.frombuffer(self.sizes, dtype=np.int64))

    def vertex_uv(self, path: Path, n: int) -> np.ndarray | None:
        if not self.texcoords or not self.uv_complete:
            return None
        texcoords = np.frombuffer(self.texcoords, dtype=np.float64).reshape(-1, 2)
        uv_corners = _in_range(self.uv_corners, len(texcoords), "texture coordinate", path)
        return per_vertex_uv(np.frombuffer(self.corners, dtype=np.int64), texcoords[uv_corners], n)


def _in_range(ids: array[int], count: int, what: str, path: Path) -> np.ndarray:
    """0-based ``ids`` as an array, refused if one is beyond the ``count`` the file defines."""
    values = np.frombuffer(ids, dtype=np.int64)
    if len(values) and values.max() >= count:
        raise InvalidInput(
            f"{path.name}: a face refers to {what} {values.max() + 1}, but the file has only {count} of them "
            "(OBJ ids start at 1)"
        )
    return values


def _index(token: bytes, count: int, what: str) -> int:
    """A 0-based id from an OBJ id: 1-based, or negative counting back from the latest of ``count``."""
    index = int(numbers([token], int)[0])
    if index > 0:
        return index - 1
    if index == 0:
        raise ValueError(f"{what} id 0: OBJ ids start at 1")
    if -index > count:
        raise ValueError(f"relative {what} id {index} reaches before the first one (there are {count} so far)")
    return count + index


def _inside(folder: Path, name: bytes | str) -> Path | None:
    """``folder/name`` if it is a file inside ``folder``; an absolute name or one with ``..`` is not touched."""
    if isinstance(name, bytes):
        try:
            name = name.decode()
        except UnicodeDecodeError:
            return None
    relative = PurePath(name)
    if not name or relative.is_absolute() or ".." in relative.parts:
        return None
    candidate = folder / relative
    try:
        inside = candidate.resolve().is_relative_to(folder.resolve())  # not a symbolic link pointing out
        return candidate if inside and candidate.is_file() else None
    except (OSError, ValueError):  # a name too long, a NUL byte
        return None


def _texture_from_mtl(folder: Path, mtllib: bytes | None) -> str | None:
    mtl = _inside(folder, mtllib) if mtllib else None
    if mtl is None:
        return None
    with open(mtl, "rb") as f:
        for line in f:
            parts = line.split()
            if parts and parts[0] == b"map_Kd" and len(parts) > 1:
                image = _inside(mtl.parent, parts[-1])
                return str(image) if image else None
    return None


def write_obj(mesh: Mesh, path: Path, uv: np.ndarray | None, material: str | None = None) -> None:
    """``material``: the name of a material in ``<material>.mtl`` beside the file, which the faces use."""
    with open(path, "w") as f:
        f.write(f"# written by curvefm: {mesh.n_vertices} vertices, {len(mesh.faces)} faces\n")
        if material:
            f.write(f"mtllib {material}.mtl\nusemtl {material}\n")
        np.savetxt(f, mesh.vertices, fmt="v %.17g %.17g %.17g")
        faces = mesh.faces + 1
        if uv is not None:
            np.savetxt(f, uv, fmt="vt %.9g %.9g")
            np.savetxt(f, np.repeat(faces, 2, axis=1), fmt="f %d/%d %d/%d %d/%d")
        else:
            np.savetxt(f, faces, fmt="f %d %d %d")
