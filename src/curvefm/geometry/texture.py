"""Texture coordinates for shapes that have none: a cylindrical parameterisation about the principal axis.

Good enough to show a checkerboard carried by a map on elongated shapes (people, animals): ``v`` runs along
the longest axis, ``u`` around it. There is one seam where ``u`` wraps from 1 to 0. And the image those
coordinates show: the web UI's checkerboard.
"""

from __future__ import annotations

import colorsys
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from curvefm.geometry.mesh import Mesh


def cylindrical_uv(vertices: np.ndarray) -> np.ndarray:
    centred = vertices - vertices.mean(axis=0)
    _, _, axes = np.linalg.svd(centred, full_matrices=False)
    local = centred @ axes.T  # coordinates along the principal axes, longest first
    along = local[:, 0]
    v = (along - along.min()) / max(np.ptp(along), 1e-300)
    u = (np.arctan2(local[:, 2], local[:, 1]) + np.pi) / (2 * np.pi)
    return np.column_stack([u, v])


def texture_coordinates(mesh: Mesh) -> np.ndarray:
    """The mesh's own uv if it has them, else the generated cylindrical ones."""
    return mesh.uv if mesh.uv is not None else cylindrical_uv(mesh.vertices)


def checkerboard_image(tiles: int = 12, size: int = 512) -> np.ndarray:
    """The web UI's checkerboard (``service/static/views/colors.js``) as an RGB image, ``size x size x 3`` uint8,
    row 0 at the top (v = 1): the hue turns with u and the saturation grows with v, so a carried texture shows
    orientation as well as distortion."""
    colours = np.zeros((tiles, tiles, 3))  # [tile row from the top, tile column]
    for i in range(tiles):
        for j in range(tiles):
            lightness = 0.80 if (i + j) % 2 == 0 else 0.52
            saturation = 0.25 + 0.5 * j / (tiles - 1)
            colours[tiles - 1 - j, i] = colorsys.hls_to_rgb(i / tiles, lightness, saturation)  # v runs up
    tile_of_pixel = np.arange(size) * tiles // size
    return np.round(colours[np.ix_(tile_of_pixel, tile_of_pixel)] * 255).astype(np.uint8)
