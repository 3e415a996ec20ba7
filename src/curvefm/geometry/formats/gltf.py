"""glTF and GLB, read with trimesh (``process=False`` keeps the buffer's vertex order).

Only self-contained files are read: every buffer and image must be inside the file (a ``data:`` URI, or
the GLB's binary chunk). A ``uri`` naming another file (``mesh.bin``, ``/etc/passwd``, ``../x``) is refused
before trimesh sees the file, and trimesh is given the bytes, not the path, so it cannot open anything else.
Accessor counts are checked first: all accessors together may declare at most twice the file's size in bytes
(trimesh allocates zeros for an accessor without a buffer view, whatever its count), and vertex positions at
most the vertex limit.
"""

from __future__ import annotations

import io
import json
import struct
from pathlib import Path
from typing import Any, cast

import numpy as np

from curvefm.errors import InvalidInput
from curvefm.geometry.formats.reading import check_declared_size
from curvefm.geometry.mesh import Mesh
from curvefm.geometry.validation import build_mesh, check_vertex_count

GLB_MAGIC, GLB_JSON = b"glTF", b"JSON"
COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
ACCESSOR_BYTES_PER_FILE_BYTE = 2
"""Accessors read bytes the file holds (a few may share them): more than this many per file byte is a lie,
and trimesh allocates what an accessor without a buffer view declares."""


def read_gltf(path: Path, name: str) -> Mesh:
    data = path.read_bytes()
    _check_document(_document(data, path), path, len(data))
    # open3d's glTF reader (assimp) reorders vertices; trimesh with process=False keeps the buffer order
    import trimesh

    try:
        # typed as any Geometry; with force="mesh" it is one Trimesh
        scene = cast(
            trimesh.Trimesh,
            trimesh.load(io.BytesIO(data), file_type=path.suffix[1:].lower(), process=False, force="mesh"),
        )
    except Exception as exc:  # trimesh raises many types for broken files
        raise InvalidInput(f"could not read {path.name} as glTF: {exc}") from None
    uv = getattr(scene.visual, "uv", None)
    return build_mesh(np.asarray(scene.vertices), np.asarray(scene.faces), uv, name=name)


def _document(data: bytes, path: Path) -> dict[str, Any]:
    """The JSON part: the whole of a .gltf, the first chunk of a .glb (whose header is checked)."""
    text = data
    if path.suffix.lower() == ".glb":
        if data[:4] != GLB_MAGIC or len(data) < 20:
            raise InvalidInput(f"{path.name} is not a GLB file: it does not start with 'glTF'")
        _, length, chunk, kind = struct.unpack_from("<4I", data, 4)
        if length != len(data) or kind != int.from_bytes(GLB_JSON, "little") or 20 + chunk > len(data):
            raise InvalidInput(f"{path.name} is not a valid GLB file: its header does not match its size")
        text = data[20 : 20 + chunk]
    try:
        document = json.loads(text)
    except (ValueError, RecursionError) as exc:  # UnicodeDecodeError is a ValueError
        raise InvalidInput(f"could not read {path.name} as glTF: its JSON is invalid ({exc})") from None
    if not isinstance(document, dict):
        raise InvalidInput(f"could not read {path.name} as glTF: its JSON is not an object")
    return document


def _check_document(document: dict[str, Any], path: Path, size: int) -> None:
    try:
        _check_uris(document, path)
        accessors = document.get("accessors", [])
        declared = sum(int(a["count"]) * COMPONENT_BYTES[a["componentType"]] * COMPONENTS[a["type"]] for a in accessors)
        positions = sum(
            int(accessors[p["attributes"]["POSITION"]]["count"])
            for mesh in document.get("meshes", [])
            for p in mesh["primitives"]
            if "POSITION" in p.get("attributes", {})
        )
    except (AttributeError, TypeError, KeyError, IndexError, ValueError, OverflowError):
        raise InvalidInput(f"could not read {path.name} as glTF: its JSON does not have the glTF structure") from None
    check_declared_size(path, f"accessors of {declared} bytes", declared // ACCESSOR_BYTES_PER_FILE_BYTE, size)
    check_vertex_count(positions, f"{path.name} declares")


def _check_uris(document: dict[str, Any], path: Path) -> None:
    for kind in ("buffers", "images"):
        for i, item in enumerate(document.get(kind, [])):
            uri = item.get("uri", "data:")
            if not (isinstance(uri, str) and uri.startswith("data:")):
                raise InvalidInput(
                    f"{path.name} refers to another file ({kind} {i}: '{str(uri)[:80]}'); only self-contained "
                    "glTF is accepted: embed the data (data: URIs) or upload a .glb"
                )
