"""Farthest-point sampling of mesh vertices by geodesic distance."""

from __future__ import annotations

import numpy as np
from scipy.sparse.csgraph import dijkstra

from curvefm.errors import InvalidInput
from curvefm.geometry.geodesics import checked_ids, geodesic_graph
from curvefm.geometry.mesh import Mesh

# ----------------------------------------------------------------------------------------------------------
# Farthest point sampling


def farthest_point_sampling(mesh: Mesh, count: int, seed_vertex: int = 0, *, diagonals: bool = True) -> np.ndarray:
    """``count`` well-spread vertices (internal ids) by farthest-point sampling with graph geodesics.

    The first sample is ``seed_vertex``; each next one is the vertex farthest from all samples so far.
    Each Dijkstra is limited to the current covering radius (nothing farther can change), so the cost
    shrinks as the samples densify. Vertices of other components are reached first (infinite distance).
    """
    n = mesh.n_vertices
    if not 1 <= int(count) <= n:
        raise InvalidInput(f"farthest_point_sampling: count must be between 1 and {n} (the vertex count), got {count}")
    seed = int(checked_ids([seed_vertex], n, "seed vertex")[0])
    graph = geodesic_graph(mesh, diagonals)
    samples = np.empty(int(count), dtype=np.int64)
    samples[0] = seed
    nearest = np.full(n, np.inf)
    for s in range(int(count)):
        if s > 0:
            samples[s] = int(np.argmax(nearest))
        radius = float(nearest.max())
        d = dijkstra(graph, directed=True, indices=int(samples[s]), limit=radius)  # type: ignore[call-overload]  # scipy-stubs: indices as an array only; scipy takes one int (1-D result)
        np.minimum(nearest, d, out=nearest)
    return samples
