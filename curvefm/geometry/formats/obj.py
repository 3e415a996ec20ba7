"""Wavefront OBJ, read by our own parser: open3d's reorders vertices (by first use) and splits them at
uv seams, which would silently break vertex ids and ground truth.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from curvefm.errors import InvalidInput
from curvefm.geometry.mesh import Mesh
from curvefm.geometry.validation import build_mesh, per_vertex_uv


def read_obj(path: Path, name: str) -> Mesh:
    vertices, texcoords, polys, poly_uv = [], [], [], []
    mtllib = None
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            for lineno, line in enumerate(f, 1):
                parts = line.split()
                if not parts:
                    continue
                tag = parts[0]
                if tag == "v":
                    vertices.append([float(x) for x in parts[1:4]])
                elif tag == "vt":
                    texcoords.append([float(x) for x in parts[1:3]])
                elif tag == "f":
                    corners = [c.split("/") for c in parts[1:]]
                    polys.append([_obj_index(c[0], len(vertices), lineno) for c in corners])
                    if all(len(c) > 1 and c[1] for c in corners):
                        poly_uv.append([_obj_index(c[1], len(texcoords), lineno) for c in corners])
                    else:
                        poly_uv.append(None)
                elif tag == "mtllib" and len(parts) > 1:
                    mtllib = path.parent / " ".join(parts[1:])
    except ValueError as exc:
        raise InvalidInput(f"{path.name} is not a valid OBJ file: {exc}") from None
    if not vertices:
        raise InvalidInput(f"could not read any vertices from {path.name}: the file is empty or malformed")
    uv = _obj_vertex_uv(len(vertices), polys, poly_uv, texcoords)
    return build_mesh(vertices, polys, uv, name=name, texture_path=_texture_from_mtl(mtllib))


def _obj_index(token: str, count: int, lineno: int) -> int:
    index = int(token)
    return index - 1 if index > 0 else count + index  # OBJ is 1-based; negative counts from the end


def _obj_vertex_uv(n: int, polys, poly_uv, texcoords) -> np.ndarray | None:
    if not texcoords or any(p is None for p in poly_uv):
        return None
    tc = np.asarray(texcoords)
    corner_v = np.concatenate([np.asarray(p) for p in polys])
    corner_t = np.concatenate([np.asarray(p) for p in poly_uv])
    if corner_t.max() >= len(tc) or corner_t.min() < 0:
        raise InvalidInput("OBJ face refers to a texture coordinate that does not exist")
    return per_vertex_uv(corner_v, tc[corner_t], n)


def _texture_from_mtl(mtllib: Path | None) -> str | None:
    if mtllib is None or not mtllib.is_file():
        return None
    for line in mtllib.read_text(errors="replace").splitlines():
        parts = line.split()
        if parts and parts[0] == "map_Kd" and len(parts) > 1:
            image = mtllib.parent / parts[-1]
            return str(image) if image.is_file() else None
    return None


def write_obj(mesh: Mesh, path: Path, uv: np.ndarray | None) -> None:
    with open(path, "w") as f:
        f.write(f"# written by curvefm: {mesh.n_vertices} vertices, {len(mesh.faces)} faces\n")
        np.savetxt(f, mesh.vertices, fmt="v %.17g %.17g %.17g")
        faces = mesh.faces + 1
        if uv is not None:
            np.savetxt(f, uv, fmt="vt %.9g %.9g")
            np.savetxt(f, np.repeat(faces, 2, axis=1), fmt="f %d/%d %d/%d %d/%d")
        else:
            np.savetxt(f, faces, fmt="f %d %d %d")
