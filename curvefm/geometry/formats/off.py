"""OFF files, read and written here (open3d parses OFF coordinates as float32 and writes 7 digits).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from curvefm.errors import InvalidInput
from curvefm.geometry.mesh import Mesh
from curvefm.geometry.validation import build_mesh


def read_off(path: Path, name: str) -> Mesh:
    # read here rather than by open3d, whose OFF reader parses coordinates as float32
    lines = (line.split("#", 1)[0].split() for line in path.read_text(errors="replace").splitlines())
    tokens = [t for t in lines if t]
    if not tokens or not tokens[0][0].upper().endswith("OFF"):
        raise InvalidInput(f"{path.name} is not an OFF file: it does not start with 'OFF'")
    try:
        counts = tokens[0][1:] or tokens[1]
        n_vertices, n_faces = int(counts[0]), int(counts[1])
        body = tokens[1 if tokens[0][1:] else 2 :]
        if len(body) < n_vertices + n_faces:
            raise ValueError(f"header promises {n_vertices} vertices and {n_faces} faces, file is shorter")
        vertex_rows, face_rows = body[:n_vertices], body[n_vertices : n_vertices + n_faces]
        if any(len(row) < 3 for row in vertex_rows):
            raise ValueError("a vertex line has fewer than three coordinates")
        vertices = np.array([row[:3] for row in vertex_rows], dtype=np.float64)
        if any(len(row) < 1 + int(row[0]) for row in face_rows):
            raise ValueError("a face line lists fewer vertex ids than it declares")
        if all(row[0] == "3" for row in face_rows):  # the common all-triangle file: one array conversion
            faces = np.array([row[1:4] for row in face_rows], dtype=np.int64)
        else:
            faces = [[int(i) for i in row[1 : 1 + int(row[0])]] for row in face_rows]
    except (ValueError, IndexError) as exc:
        raise InvalidInput(f"{path.name} is not a valid OFF file: {exc}") from None
    return build_mesh(vertices, faces, name=name)


def write_off(mesh: Mesh, path: Path) -> None:
    # written here rather than by open3d, whose OFF writer rounds coordinates to 7 digits
    with open(path, "w") as f:
        f.write(f"OFF\n{mesh.n_vertices} {len(mesh.faces)} 0\n")
        np.savetxt(f, mesh.vertices, fmt="%.17g")
        np.savetxt(f, mesh.faces, fmt="3 %d %d %d")
