"""Discrete Laplace-Beltrami operators: the cotangent Laplacian with lumped (barycentric) mass.

Sign convention: ``L`` is positive semi-definite (``L @ ones == 0``), so ``L phi = lambda A phi`` has
``lambda >= 0``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def cotangent_laplacian(vertices: np.ndarray, faces: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """Return ``(L, mass)``: the PSD cotangent stiffness matrix and lumped vertex areas (one third of each
    incident triangle)."""
    n = len(vertices)
    p = vertices[faces]  # (f, 3 corners, 3 coords)
    cot = np.empty((len(faces), 3))
    for corner in range(3):
        a = p[:, (corner + 1) % 3] - p[:, corner]
        b = p[:, (corner + 2) % 3] - p[:, corner]
        cross = np.linalg.norm(np.cross(a, b), axis=1)
        cot[:, corner] = np.einsum("ij,ij->i", a, b) / np.maximum(cross, 1e-300)
    # the cotangent at corner c weighs the opposite edge (c+1, c+2)
    i = faces[:, [1, 2, 0]].ravel()
    j = faces[:, [2, 0, 1]].ravel()
    w = 0.5 * cot.ravel()
    off = sp.coo_matrix((np.r_[-w, -w], (np.r_[i, j], np.r_[j, i])), shape=(n, n)).tocsr()
    L = off - sp.diags(np.asarray(off.sum(axis=1)).ravel())
    areas = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    mass = np.bincount(faces.ravel(), weights=np.repeat(areas / 3.0, 3), minlength=n)
    return L.tocsr(), mass


def robust_laplacian(vertices: np.ndarray, faces: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """The intrinsic-Delaunay 'tufted' Laplacian of Sharp & Crane 2020 (package ``robust_laplacian``):
    well behaved on poor triangulations and non-manifold meshes."""
    import robust_laplacian as rl

    L, M = rl.mesh_laplacian(np.ascontiguousarray(vertices), np.ascontiguousarray(faces))
    return sp.csr_matrix(L), np.asarray(M.diagonal()).ravel()
