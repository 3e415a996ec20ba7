"""Exact nearest neighbours in high dimension (spectral embeddings: 20-200 dimensions).

Trees are useless at this dimension (cKDTree: 156 s for 30k x 30k in 120 dimensions here). We use faiss's
exact ``IndexFlatL2`` (2.7 s), or blocked float32 matrix products in numpy (3.4 s) as the dependency-free path.
"""

from __future__ import annotations

import numpy as np

from curvefm.errors import InvalidInput

BLOCK = 4096


def nearest_neighbors(data: np.ndarray, queries: np.ndarray, method: str = "faiss") -> np.ndarray:
    """For each row of ``queries``, the index of the nearest row of ``data`` (Euclidean)."""
    data = np.ascontiguousarray(data, dtype=np.float32)
    queries = np.ascontiguousarray(queries, dtype=np.float32)
    if method == "faiss":
        import faiss

        index = faiss.IndexFlatL2(data.shape[1])
        index.add(data)
        return index.search(queries, 1)[1][:, 0].astype(np.int64)
    if method == "blocked":
        return _blocked_nearest(data, queries)
    raise InvalidInput(f"unknown nearest-neighbour method {method!r}; methods are faiss, blocked")


def _blocked_nearest(data: np.ndarray, queries: np.ndarray) -> np.ndarray:
    # |q - d|^2 = |q|^2 - 2 q.d + |d|^2; |q|^2 does not change the argmin
    data_sq = np.einsum("ij,ij->i", data, data)
    out = np.empty(len(queries), dtype=np.int64)
    for start in range(0, len(queries), BLOCK):
        block = queries[start : start + BLOCK]
        out[start : start + BLOCK] = np.argmin(data_sq[None, :] - 2.0 * (block @ data.T), axis=1)
    return out
