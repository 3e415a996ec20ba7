"""Texture coordinates for shapes that have none: a cylindrical parameterisation about the principal axis.

Good enough to show a checkerboard carried by a map on elongated shapes (people, animals): ``v`` runs along
the longest axis, ``u`` around it. There is one seam where ``u`` wraps from 1 to 0.
"""

from __future__ import annotations

import numpy as np


def cylindrical_uv(vertices: np.ndarray) -> np.ndarray:
    centred = vertices - vertices.mean(axis=0)
    _, _, axes = np.linalg.svd(centred, full_matrices=False)
    local = centred @ axes.T  # coordinates along the principal axes, longest first
    along = local[:, 0]
    v = (along - along.min()) / max(np.ptp(along), 1e-300)
    u = (np.arctan2(local[:, 2], local[:, 1]) + np.pi) / (2 * np.pi)
    return np.column_stack([u, v])


def texture_coordinates(mesh) -> np.ndarray:
    """The mesh's own uv if it has them, else the generated cylindrical ones."""
    return mesh.uv if mesh.uv is not None else cylindrical_uv(mesh.vertices)
