"""Surfaces embedded in R^d so that Euclidean distances follow geodesic ones, and closest points on them.

Used by Reversible Harmonic Maps (``plugins/rhm.py``), whose projection steps search for closest points in
such an embedding so that "close" means intrinsically close.

:func:`geodesic_embedding`: metric multidimensional scaling of graph-geodesic distances between
farthest-point samples (classical MDS, then SMACOF stress majorisation), extended to every vertex by
biharmonic interpolation (minimise ``x^T L A^-1 L x`` with the samples fixed), as Ezuz et al. 2018 do.

:func:`closest_points`: for each query point, the closest point on the triangles of an embedded mesh, as
face vertices and barycentric weights. Candidates are the triangles around the ``candidates`` nearest
vertices (a k-d tree query: these embeddings have 8-16 dimensions and lie on a 2-manifold, where trees are
10x faster than brute force).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from scipy.spatial import cKDTree

from curvefm.geometry import Mesh, farthest_point_sampling, geodesic_distances


def geodesic_embedding(
    mesh: Mesh,
    L: sp.csr_matrix | sp.csc_matrix,
    mass: np.ndarray,
    dim: int = 8,
    samples: int = 500,
    smacof_iterations: int = 100,
) -> np.ndarray:
    """(n, dim) coordinates whose Euclidean distances approximate geodesic distances on ``mesh``.

    ``L`` (PSD cotangent Laplacian) and ``mass`` (lumped vertex areas) define the biharmonic extension from
    the ``samples`` farthest-point samples to all vertices.
    """
    ids = farthest_point_sampling(mesh, min(samples, mesh.n_vertices))
    D = geodesic_distances(mesh, ids)[:, ids]
    D = 0.5 * (D + D.T)  # graph distances from each source agree up to round-off; make it exactly symmetric
    Y = smacof(D, classical_mds(D, dim), smacof_iterations)
    return biharmonic_extension(L, mass, ids, Y)


def classical_mds(D: np.ndarray, dim: int) -> np.ndarray:
    """Torgerson's classical scaling: the top eigenvectors of the double-centred squared distances."""
    B = -0.5 * D**2
    B -= B.mean(axis=0)
    B -= B.mean(axis=1, keepdims=True)
    w, v = np.linalg.eigh(B)
    w, v = w[::-1][:dim], v[:, ::-1][:, :dim]
    return v * np.sqrt(np.maximum(w, 0.0))


def smacof(D: np.ndarray, Y: np.ndarray, iterations: int, tol: float = 1e-6) -> np.ndarray:
    """Metric MDS by stress majorisation (Guttman transform, unit weights), from ``Y``."""
    n = len(D)
    previous = np.inf
    for _ in range(iterations):
        sq = np.einsum("ij,ij->i", Y, Y)
        d = np.sqrt(np.maximum(sq[:, None] + sq[None, :] - 2.0 * Y @ Y.T, 0.0))
        stress = np.sum((d - D) ** 2)
        if previous - stress <= tol * stress:
            break
        previous = stress
        B = -np.divide(D, d, out=np.zeros_like(D), where=d > 1e-12)
        np.fill_diagonal(B, 0.0)
        np.fill_diagonal(B, -B.sum(axis=1))
        Y = B @ Y / n
    return Y


def biharmonic_extension(
    L: sp.csr_matrix | sp.csc_matrix, mass: np.ndarray, fixed: np.ndarray, values: np.ndarray
) -> np.ndarray:
    """Values at every vertex minimising the biharmonic energy ``x^T L A^-1 L x`` with ``x[fixed] = values``."""
    n = L.shape[0]
    Q = (L @ sp.diags(1.0 / mass) @ L).tocsr()
    free = np.setdiff1d(np.arange(n), fixed)
    out = np.empty((n, values.shape[1]))
    out[fixed] = values
    out[free] = -splu(Q[free][:, free].tocsc()).solve(np.asarray(Q[free][:, fixed] @ values))
    return out


def vertex_faces(faces: np.ndarray, n: int) -> np.ndarray:
    """(n, max valence) ids of the faces around each vertex, padded with -1."""
    corner_vertex = faces.ravel()
    corner_face = np.repeat(np.arange(len(faces)), 3)
    order = np.argsort(corner_vertex, kind="stable")
    corner_vertex, corner_face = corner_vertex[order], corner_face[order]
    counts = np.bincount(corner_vertex, minlength=n)
    slot = np.arange(len(corner_vertex)) - np.repeat(np.cumsum(counts) - counts, counts)
    out = np.full((n, counts.max()), -1, dtype=np.int64)
    out[corner_vertex, slot] = corner_face
    return out


def closest_points(
    points: np.ndarray, faces: np.ndarray, queries: np.ndarray, candidates: int = 3, chunk: int = 4096
) -> tuple[np.ndarray, np.ndarray]:
    """Closest point to each query on the mesh with vertex coordinates ``points`` (n, d).

    Returns ``(corners, weights)``, both (q, 3): the face's vertex ids and the barycentric weights.
    """
    around = vertex_faces(faces, len(points))
    near = cKDTree(points).query(queries, k=candidates, workers=-1)[1].reshape(len(queries), -1)
    corners = np.empty((len(queries), 3), dtype=np.int64)
    weights = np.empty((len(queries), 3))
    for start in range(0, len(queries), chunk):
        block = slice(start, start + chunk)
        cand = around[near[block]].reshape(len(near[block]), -1)
        query, face = np.nonzero(cand >= 0)
        face = cand[query, face]
        tri = faces[face]
        w, dist = closest_on_triangles(queries[block][query], points[tri[:, 0]], points[tri[:, 1]], points[tri[:, 2]])
        order = np.lexsort((dist, query))
        best = order[np.r_[True, query[order][1:] != query[order][:-1]]]
        corners[start + query[best]] = tri[best]
        weights[start + query[best]] = w[best]
    return corners, weights


def closest_on_triangles(q: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row-wise closest point to ``q`` on triangle ``(a, b, c)`` in R^d: barycentric weights (m, 3) and squared
    distances (m,). The unconstrained minimiser if it lies inside, else the best of the three edges (a convex
    quadratic's minimum over a triangle lies on its boundary when the free minimum is outside)."""
    e0, e1, r = b - a, c - a, q - a
    d00, d01, d11 = (np.einsum("ij,ij->i", x, y) for x, y in ((e0, e0), (e0, e1), (e1, e1)))
    r0, r1 = np.einsum("ij,ij->i", r, e0), np.einsum("ij,ij->i", r, e1)
    det = d00 * d11 - d01**2
    ok = det > 1e-12 * d00 * d11
    safe = np.where(ok, det, 1.0)
    s, t = (d11 * r0 - d01 * r1) / safe, (d00 * r1 - d01 * r0) / safe
    inside = ok & (s >= 0) & (t >= 0) & (s + t <= 1)
    options = [(np.c_[1 - s - t, s, t], inside)]
    corners = (a, b, c)
    for i, j in ((0, 1), (1, 2), (2, 0)):
        edge = corners[j] - corners[i]
        u = np.einsum("ij,ij->i", q - corners[i], edge) / np.maximum(np.einsum("ij,ij->i", edge, edge), 1e-300)
        u = np.clip(u, 0.0, 1.0)
        w = np.zeros((len(q), 3))
        w[:, i], w[:, j] = 1.0 - u, u
        options.append((w, np.ones(len(q), dtype=bool)))
    best_w, best_d = np.zeros((len(q), 3)), np.full(len(q), np.inf)
    for w, valid in options:
        p = w[:, :1] * a + w[:, 1:2] * b + w[:, 2:] * c
        d = np.where(valid, np.einsum("ij,ij->i", q - p, q - p), np.inf)
        better = d < best_d
        best_w[better], best_d[better] = w[better], d[better]
    return best_w, best_d
