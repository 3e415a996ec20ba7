"""glTF and GLB, read with trimesh (``process=False`` keeps the buffer's vertex order).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from curvefm.errors import InvalidInput
from curvefm.geometry.mesh import Mesh
from curvefm.geometry.validation import build_mesh


def read_gltf(path: Path, name: str) -> Mesh:
    # open3d's glTF reader (assimp) reorders vertices; trimesh with process=False keeps the buffer order
    import trimesh

    try:
        scene = trimesh.load(path, process=False, force="mesh")
    except Exception as exc:  # trimesh raises many types for broken files
        raise InvalidInput(f"could not read {path.name} as glTF: {exc}") from None
    uv = getattr(scene.visual, "uv", None)
    return build_mesh(np.asarray(scene.vertices), np.asarray(scene.faces), uv, name=name)
