"""Triangle meshes: loading, saving, validation and identity.

Index convention: a :class:`Mesh` works with *internal* vertex ids ``0..n-1``. When a file has vertices that
no face uses, they are dropped; ``file_ids[i]`` is the id in the file of internal vertex ``i`` and
:meth:`Mesh.internal_ids` translates the other way, so ids a user read off the file stay valid.
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict, dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike

from curvefm.cache import LRU
from curvefm.errors import Conflict, InvalidInput


@dataclass
class MeshReport:
    """What validation changed or noticed. Changes keep user ids valid; notes are not fatal."""

    triangulated_polygons: int = 0
    degenerate_faces_removed: int = 0
    unreferenced_vertices_removed: int = 0
    non_manifold_edges: int = 0
    boundary_edges: int = 0
    components: int = 1
    warnings: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True, eq=False)
class Mesh:
    vertices: np.ndarray  # (n, 3) float64
    faces: np.ndarray  # (f, 3) int64, internal ids
    file_ids: np.ndarray  # (n,) int64: id in the source file of each internal vertex
    n_file_vertices: int
    report: MeshReport
    uv: np.ndarray | None = None  # (n, 2) per-vertex texture coordinates, if the file had them
    texture_path: str | None = None  # texture image named by the file's material, if any
    name: str = ""
    derived: LRU[Any] = field(default_factory=lambda: LRU(maxsize=8), init=False, repr=False)
    """Values other modules compute from this mesh (geodesic graphs, the diameter, a tracer's weighted graphs): a
    mesh never changes, so what is derived from it lives and dies with it. Bounded: user parameters make keys."""

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @cached_property
    def content_hash(self) -> str:
        """Identity of the geometry, connectivity, uv and id map: equal meshes hash equal in any format."""
        h = hashlib.sha256()
        for array in (self.vertices, self.faces, self.file_ids, self.uv):
            if array is not None:
                h.update(np.ascontiguousarray(array).data)  # its bytes, without a copy of them
            h.update(b"|")
        return h.hexdigest()[:32]

    @cached_property
    def edges(self) -> np.ndarray:
        """Unique undirected edges (E, 2), smaller id first."""
        keys = edge_keys(self.faces, self.n_vertices)
        return np.column_stack(np.divmod(np.unique(keys), self.n_vertices))

    @cached_property
    def edge_lengths(self) -> np.ndarray:
        lengths: np.ndarray = np.linalg.norm(self.vertices[self.edges[:, 0]] - self.vertices[self.edges[:, 1]], axis=1)
        return lengths

    @cached_property
    def face_areas(self) -> np.ndarray:
        v = self.vertices[self.faces]
        areas: np.ndarray = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
        return areas

    @property
    def area(self) -> float:
        return float(self.face_areas.sum())

    @cached_property
    def edge_graph(self) -> sp.csr_matrix:
        """Symmetric sparse adjacency weighted by Euclidean edge length."""
        return edge_weight_graph(self.n_vertices, self.edges, self.edge_lengths)

    def internal_ids(self, ids: ArrayLike, what: str = "vertex id") -> np.ndarray:
        """Translate file vertex ids to internal ids, with a clear error for bad ones."""
        ids = np.asarray(ids)
        if ids.size and not np.issubdtype(ids.dtype, np.integer):
            if not np.all(np.mod(ids, 1) == 0):
                raise InvalidInput(f"{what}s must be integers, got {ids.tolist()}")
            ids = ids.astype(np.int64)
        ids = ids.astype(np.int64)
        bad = (ids < 0) | (ids >= self.n_file_vertices)
        if bad.any():
            raise Conflict(
                f"{what} {int(ids[bad][0])} is out of range: mesh '{self.name}' has "
                f"{self.n_file_vertices} vertices (ids are 0-based, 0..{self.n_file_vertices - 1})"
            )
        lookup = self._file_to_internal
        out: np.ndarray = lookup[ids]
        if (out < 0).any():
            raise Conflict(
                f"{what} {int(ids[out < 0][0])} of mesh '{self.name}' belongs to no face (it was dropped as "
                "unreferenced); pick a vertex on the surface"
            )
        return out

    @cached_property
    def _file_to_internal(self) -> np.ndarray:
        lookup = np.full(self.n_file_vertices, -1, dtype=np.int64)
        lookup[self.file_ids] = np.arange(self.n_vertices)
        return lookup

    def per_file_vertex(self, values: np.ndarray, fill: Any) -> np.ndarray:
        """Spread per-internal-vertex values to per-file-vertex rows (dropped vertices get ``fill``)."""
        out = np.full((self.n_file_vertices,) + values.shape[1:], fill, dtype=values.dtype)
        out[self.file_ids] = values
        return out


def edge_keys(faces: np.ndarray, n: int) -> np.ndarray:
    """One int64 key ``min * n + max`` per face-edge (3 per face, in no particular order), built one corner pair
    at a time: an upload's validation peaks at a few face-sized arrays, not at a dozen."""
    keys = np.empty(3 * len(faces), dtype=np.int64)
    for block, (a, b) in enumerate(((0, 1), (1, 2), (2, 0))):
        out = keys[block * len(faces) : (block + 1) * len(faces)]
        np.minimum(faces[:, a], faces[:, b], out=out)
        out *= n
        out += np.maximum(faces[:, a], faces[:, b])
    return keys


def edge_counts(faces: np.ndarray, n: int) -> np.ndarray:
    """How many faces share each unique undirected edge (sorted by edge key)."""
    keys = edge_keys(faces, n)
    keys.sort()
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    return np.diff(np.r_[starts, len(keys)])


def edge_weight_graph(n: int, edges: np.ndarray, weights: np.ndarray) -> sp.csr_matrix:
    i, j = edges[:, 0], edges[:, 1]
    return sp.csr_matrix((np.r_[weights, weights], (np.r_[i, j], np.r_[j, i])), shape=(n, n))
