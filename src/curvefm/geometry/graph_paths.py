"""Vertex paths on a mesh's edge graph."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from curvefm.errors import Conflict, InvalidInput


def shortest_path(graph: sp.csr_matrix, start: int, end: int) -> np.ndarray:
    """Dijkstra path from ``start`` to ``end`` (both included) on a weighted adjacency matrix."""
    if start == end:
        return np.array([start], dtype=np.int64)
    dist, pred = dijkstra(graph, directed=False, indices=int(start), return_predecessors=True)  # type: ignore[call-overload]  # scipy-stubs: indices as an array only; scipy takes one int (1-D result)
    if not np.isfinite(dist[end]):
        raise Conflict(f"vertices {start} and {end} lie on different connected components: no curve joins them")
    path = [int(end)]
    while path[-1] != start:
        path.append(int(pred[path[-1]]))
    return np.array(path[::-1], dtype=np.int64)


def check_edge_path(graph: sp.csr_matrix, path: np.ndarray) -> None:
    """Raise unless consecutive vertices of ``path`` share an edge."""
    if len(path) < 2:
        raise InvalidInput("a curve path needs at least two vertices")
    a, b = path[:-1], path[1:]
    connected = np.asarray(graph[a, b]).ravel() > 0
    if not connected.all():
        i = int(np.flatnonzero(~connected)[0])
        raise Conflict(
            f"explicit path is not edge-connected: vertices {int(a[i])} and {int(b[i])} (positions {i} and "
            f"{i + 1}) share no edge"
        )
