"""OFF files, read and written here (open3d parses OFF coordinates as float32 and writes 7 digits).

Reading streams the file line by line: one element per line, ``#`` comments and blank lines anywhere. The
header's counts are checked against the file's size (a vertex line takes at least 6 bytes, a face line 8)
and the vertex limit before anything is read, and content after the declared faces is refused.
"""

from __future__ import annotations

from array import array
from itertools import islice
from pathlib import Path

import numpy as np

from curvefm.errors import InvalidInput
from curvefm.geometry.formats.reading import TextLines, check_declared_size, counted_ids, line_errors, numbers
from curvefm.geometry.mesh import Mesh
from curvefm.geometry.validation import Polygons, build_mesh, check_vertex_count

MIN_VERTEX_LINE, MIN_FACE_LINE = len(b"0 0 0\n"), len(b"3 0 1 2\n")


def read_off(path: Path, name: str) -> Mesh:
    with open(path, "rb") as f:
        lines = TextLines(f, path, "OFF")
        with line_errors(lines):
            n_vertices, n_faces = _header(lines, path.stat().st_size)
            vertices = _vertices(lines, n_vertices)
            faces = _faces(lines, n_faces)
        lines.reject_rest(f"the {n_vertices} vertices and {n_faces} faces the header declares")
    return build_mesh(vertices, faces, name=name)


def _header(lines: TextLines, size: int) -> tuple[int, int]:
    tokens = next(iter(lines), [b""])
    if not tokens[0].upper().endswith(b"OFF"):
        raise InvalidInput(f"{lines.path.name} is not an OFF file: it does not start with 'OFF'")
    counts = tokens[1:] or next(iter(lines), [])
    if counts[:1] == [b"BINARY"]:
        raise lines.error("binary OFF is not supported; write it as text")
    if len(counts) < 2:
        raise ValueError("the header needs the numbers of vertices and faces")
    n_vertices, n_faces = numbers(counts[:2], int)
    if n_vertices < 0 or n_faces < 0:
        raise ValueError(f"negative counts in the header ({n_vertices} vertices, {n_faces} faces)")
    need = MIN_VERTEX_LINE * n_vertices + MIN_FACE_LINE * n_faces
    check_declared_size(lines.path, f"{n_vertices} vertices and {n_faces} faces", need, size)
    check_vertex_count(n_vertices, f"{lines.path.name} declares")
    return n_vertices, n_faces


def _vertices(lines: TextLines, n: int) -> np.ndarray:
    rows = (_coordinates(tokens) for tokens in islice(lines, n))
    vertices = np.fromiter(rows, dtype=np.dtype((np.float64, 3)))
    if len(vertices) < n:
        raise ValueError(f"the header promises {n} vertices, the file is shorter ({len(vertices)} vertex lines)")
    return vertices


def _coordinates(tokens: list[bytes]) -> list[float]:
    if len(tokens) < 3:
        raise ValueError("a vertex line has fewer than three coordinates")
    return numbers(tokens[:3])


def _faces(lines: TextLines, n: int) -> Polygons:
    corners, sizes = array("q"), array("q")
    for tokens in islice(lines, n):
        ids = counted_ids(tokens)
        corners.extend(ids)
        sizes.append(len(ids))
    if len(sizes) < n:
        raise ValueError(f"the header promises {n} faces, the file is shorter ({len(sizes)} face lines)")
    return Polygons(np.frombuffer(corners, dtype=np.int64), np.frombuffer(sizes, dtype=np.int64))


def write_off(mesh: Mesh, path: Path) -> None:
    # written here rather than by open3d, whose OFF writer rounds coordinates to 7 digits
    with open(path, "w") as f:
        f.write(f"OFF\n{mesh.n_vertices} {len(mesh.faces)} 0\n")
        np.savetxt(f, mesh.vertices, fmt="%.17g")
        np.savetxt(f, mesh.faces, fmt="3 %d %d %d")
