"""Display copies of big meshes: fewer triangles for a browser to draw, on vertices of the mesh itself.

A browser drawing in software (SwiftShader, the headless and GPU-less case) spends its time on triangles: at
110k vertices (220k triangles) a frame took 99 ms. A display copy has about ``vertex_count`` vertices and is
drawn instead. Its vertices are a *subset* of the mesh's, so every drawn vertex has a real id: a click picks a
real vertex, and a function on the mesh is shown by reading its rows at the display vertices (no interpolation,
and a transfer reads only those rows of the basis).

Construction: quadric decimation (open3d) to about ``vertex_count`` vertices, then each coarse vertex snapped to
a mesh vertex of its own, the nearest one that no coarse vertex nearer to it took. Snapping every coarse vertex to
its nearest mesh vertex instead merged 70-180 pairs of them on FAUST subdivided, and the merges left edges with
three or four faces: the UI then cannot tell the outside and draws both sides of every face, which cost what the
coarser mesh saved. Distinct corners keep the decimated connectivity as it is (closed and consistently wound
where the mesh is). The coarse faces follow the surface closely: on FAUST subdivided twice (110,210 -> 50,002
vertices, 1.7 units tall) 99% of the mesh's vertices lie within 8e-5 of the display copy and the worst 2.5e-3
off it, a quarter of the UI's curve tube radius (three times: 6e-5 and 9e-4).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import cached_property
from typing import cast

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from curvefm.geometry.decimation import decimate
from curvefm.geometry.mesh import Mesh, edge_keys, edge_weight_graph


@dataclass(frozen=True, eq=False)
class DisplayMesh:
    """A display copy: ``faces`` index ``vertex_ids``, the internal ids of the display vertices (ascending)."""

    vertex_ids: np.ndarray  # (d,) int64, ascending: internal id of each display vertex
    faces: np.ndarray  # (g, 3) int64: rows of vertex_ids, wound as the mesh's faces
    nearest: np.ndarray  # (n,) int64: for each vertex of the mesh, the display vertex (row) nearest to it
    n_vertices: int  # of the mesh it was made from

    @cached_property
    def key(self) -> str:
        """Identity of the vertex subset, for caches of values read at it (basis rows)."""
        return hashlib.sha256(np.ascontiguousarray(self.vertex_ids).tobytes()).hexdigest()[:32]

    def rows_of(self, vertex_ids: np.ndarray) -> np.ndarray:
        """The display rows of some internal ids (-1 for a vertex that is not a display vertex)."""
        rows = np.searchsorted(self.vertex_ids, vertex_ids).clip(max=len(self.vertex_ids) - 1)
        return np.where(self.vertex_ids[rows] == vertex_ids, rows, -1)

    def region_of(self, vertex_ids: np.ndarray) -> np.ndarray:
        """Boolean mask over the mesh: ``vertex_ids`` and every vertex whose nearest display vertex is among
        them. A set of display vertices chosen on the copy so stands for the whole surface it covers."""
        chosen = np.zeros(len(self.vertex_ids), dtype=bool)
        rows = self.rows_of(vertex_ids)
        chosen[rows[rows >= 0]] = True
        mask: np.ndarray = chosen[self.nearest]
        mask[vertex_ids] = True
        return mask

    @cached_property
    def cells(self) -> tuple[np.ndarray, np.ndarray]:
        """The mesh's vertices grouped by their nearest display vertex: ``order[starts[r]:starts[r + 1]]`` are
        those of row ``r``, ascending."""
        order = np.argsort(self.nearest, kind="stable")
        starts = np.searchsorted(self.nearest[order], np.arange(len(self.vertex_ids) + 1))
        return order, starts

    def cover(self, rows: np.ndarray) -> np.ndarray:
        """The mesh's vertices whose nearest display vertex is one of ``rows`` (distinct), ascending: reads only
        their cells, so it costs the size of the answer, not the mesh's."""
        order, starts = self.cells
        sizes = starts[rows + 1] - starts[rows]
        first = np.repeat(starts[rows] - np.cumsum(sizes) + sizes, sizes)
        return np.sort(order[first + np.arange(int(sizes.sum()))])


def display_graph(mesh: Mesh, display: DisplayMesh) -> sp.csr_matrix:
    """The display copy's edges weighted by their length (rows: display rows), cached on the mesh."""

    def build() -> sp.csr_matrix:
        count = len(display.vertex_ids)
        edges = np.column_stack(np.divmod(np.unique(edge_keys(display.faces, count)), count))
        points = mesh.vertices[display.vertex_ids]
        lengths = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
        return edge_weight_graph(len(display.vertex_ids), edges, lengths)

    graph: sp.csr_matrix = mesh.derived.get(("display graph", display.key), build)
    return graph


def display_mesh(mesh: Mesh, vertex_count: int) -> DisplayMesh:
    """A display copy of ``mesh`` with about ``vertex_count`` vertices, all of them vertices of ``mesh``."""
    coarse_vertices, coarse_faces = decimate(mesh.vertices, mesh.faces, vertex_count)
    snapped = _distinct_nearest(cKDTree(mesh.vertices), coarse_vertices)
    vertex_ids, rows = np.unique(snapped[coarse_faces], return_inverse=True)
    # cKDTree.query is typed for one point or many; with many it answers arrays
    nearest = cast(np.ndarray, cKDTree(mesh.vertices[vertex_ids]).query(mesh.vertices)[1])
    return DisplayMesh(vertex_ids, rows.reshape(-1, 3), nearest.astype(np.int64), mesh.n_vertices)


def _distinct_nearest(tree: cKDTree, points: np.ndarray, candidates: int = 8) -> np.ndarray:
    """A different vertex of the tree for each point (fewer points than vertices): points choose in the order of
    their distance to the nearest vertex, each the nearest vertex still free."""
    distances, nearest = cast(tuple[np.ndarray, np.ndarray], tree.query(points, candidates))  # arrays: many points
    taken = np.zeros(tree.n, dtype=bool)
    chosen = np.empty(len(points), dtype=np.int64)
    for i in np.argsort(distances[:, 0], kind="stable").tolist():
        found, k = [v for v in nearest[i].tolist() if not taken[v]], candidates
        while not found:  # every near vertex taken (rare): look further
            k = min(2 * k, tree.n)
            further = cast(np.ndarray, tree.query(points[i], k)[1])  # k > 1 neighbours: an array
            found = [v for v in further.tolist() if not taken[v]]
        chosen[i] = found[0]
        taken[found[0]] = True
    return chosen
