"""STL, binary and ASCII, read here with numpy; open3d only writes it.

open3d answers a truncated or malformed STL with an empty mesh and no reason. Here a file is binary exactly
when its size is
``84 + 50 * count``, ASCII when it starts with ``solid`` (then ``vertex`` lines are read, three per
``outer loop``), and refused otherwise. STL has no vertex ids: equal positions are merged, numbered by first
appearance in the file.
"""

from __future__ import annotations

from array import array
from pathlib import Path

import numpy as np

from curvefm.errors import InvalidInput
from curvefm.geometry.formats.reading import TextLines, line_errors, numbers, shown
from curvefm.geometry.mesh import Mesh
from curvefm.geometry.validation import build_mesh

HEADER_BYTES, TRIANGLE_BYTES = 84, 50
TRIANGLE = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
ASCII_KEYWORDS = {b"solid", b"facet", b"outer", b"endfacet", b"endsolid"}


def read_stl(path: Path, name: str) -> Mesh:
    with open(path, "rb") as f:
        head = f.read(HEADER_BYTES)
        size = path.stat().st_size
        declared = int.from_bytes(head[80:84], "little") if len(head) == HEADER_BYTES else None
        if declared is not None and size == HEADER_BYTES + TRIANGLE_BYTES * declared:
            corners = np.frombuffer(f.read(), dtype=TRIANGLE)["corners"].reshape(-1, 3)
        elif head.lstrip().startswith(b"solid"):
            f.seek(0)
            corners = _ascii_corners(TextLines(f, path, "ASCII STL"))
        else:
            raise InvalidInput(
                f"{path.name} is not an STL file: it does not start with 'solid', and as binary STL its "
                f"{size} bytes do not hold the {declared or 0} triangles its header declares "
                f"({HEADER_BYTES} + {TRIANGLE_BYTES} per triangle)"
            )
    if len(corners) == 0:
        raise InvalidInput(f"{path.name} has no faces: it holds no triangles")
    with np.errstate(invalid="ignore"):  # a signalling NaN warns when widened; validation refuses it
        vertices, faces = _weld(corners.astype(np.float64))
    return build_mesh(vertices, faces, name=name)


def _ascii_corners(lines: TextLines) -> np.ndarray:
    corners, in_loop = array("d"), 0
    with line_errors(lines):
        for tokens in lines:
            keyword = tokens[0]
            if keyword == b"vertex":
                if len(tokens) != 4:
                    raise ValueError("a vertex line needs three coordinates")
                corners.extend(numbers(tokens[1:]))
                in_loop += 1
            elif keyword == b"endloop":
                if in_loop != 3:
                    raise ValueError(f"a facet has {in_loop} vertices; STL facets are triangles")
                in_loop = 0
            elif keyword not in ASCII_KEYWORDS:
                raise ValueError(f"unexpected {shown(keyword)} in an ASCII STL")
    if in_loop:
        raise lines.error("the file ends inside a facet")
    return np.frombuffer(corners, dtype=np.float64).reshape(-1, 3)


def _weld(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """STL stores every triangle's corners separately and no vertex ids: merge equal positions, numbering
    vertices in order of first appearance in the file (the only order an STL file defines)."""
    unique, first, inverse = np.unique(corners, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return unique[order], rank[inverse.ravel()].reshape(-1, 3)
