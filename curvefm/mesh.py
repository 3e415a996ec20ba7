"""Triangle meshes: loading, saving, validation and identity.

Index convention: a :class:`Mesh` works with *internal* vertex ids ``0..n-1``. When a file has vertices that
no face uses, they are dropped; ``file_ids[i]`` is the id in the file of internal vertex ``i`` and
:meth:`Mesh.internal_ids` translates the other way, so ids a user read off the file stay valid.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import asdict, dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from curvefm.errors import CurvefmError

OPEN3D_FORMATS = {".ply", ".stl"}
GLTF_FORMATS = {".glb", ".gltf"}
SUPPORTED_FORMATS = sorted(OPEN3D_FORMATS | GLTF_FORMATS | {".obj", ".off"})


def max_vertices() -> int:
    """Largest accepted vertex count (``CURVEFM_MAX_VERTICES``, default two million)."""
    return int(os.environ.get("CURVEFM_MAX_VERTICES", 2_000_000))


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

    def as_dict(self) -> dict:
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

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @cached_property
    def content_hash(self) -> str:
        """Identity of the geometry, connectivity, uv and id map: equal meshes hash equal in any format."""
        h = hashlib.sha256()
        for array in (self.vertices, self.faces, self.file_ids, self.uv):
            if array is not None:
                h.update(np.ascontiguousarray(array).tobytes())
            h.update(b"|")
        return h.hexdigest()[:32]

    @cached_property
    def edges(self) -> np.ndarray:
        """Unique undirected edges (E, 2), smaller id first."""
        keys, _ = edge_keys(self.faces, self.n_vertices)
        return np.column_stack(np.divmod(np.unique(keys), self.n_vertices))

    @cached_property
    def edge_lengths(self) -> np.ndarray:
        return np.linalg.norm(self.vertices[self.edges[:, 0]] - self.vertices[self.edges[:, 1]], axis=1)

    @cached_property
    def face_areas(self) -> np.ndarray:
        v = self.vertices[self.faces]
        return 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)

    @property
    def area(self) -> float:
        return float(self.face_areas.sum())

    @cached_property
    def edge_graph(self) -> sp.csr_matrix:
        """Symmetric sparse adjacency weighted by Euclidean edge length."""
        return edge_weight_graph(self.n_vertices, self.edges, self.edge_lengths)

    def internal_ids(self, ids, what: str = "vertex id") -> np.ndarray:
        """Translate file vertex ids to internal ids, with a clear error for bad ones."""
        ids = np.asarray(ids)
        if ids.size and not np.issubdtype(ids.dtype, np.integer):
            if not np.all(np.mod(ids, 1) == 0):
                raise CurvefmError(f"{what}s must be integers, got {ids.tolist()}")
            ids = ids.astype(np.int64)
        ids = ids.astype(np.int64)
        bad = (ids < 0) | (ids >= self.n_file_vertices)
        if bad.any():
            raise CurvefmError(
                f"{what} {int(ids[bad][0])} is out of range: mesh '{self.name}' has "
                f"{self.n_file_vertices} vertices (ids are 0-based, 0..{self.n_file_vertices - 1})"
            )
        lookup = self._file_to_internal
        out = lookup[ids]
        if (out < 0).any():
            raise CurvefmError(
                f"{what} {int(ids[out < 0][0])} of mesh '{self.name}' belongs to no face (it was dropped as "
                "unreferenced); pick a vertex on the surface"
            )
        return out

    @cached_property
    def _file_to_internal(self) -> np.ndarray:
        lookup = np.full(self.n_file_vertices, -1, dtype=np.int64)
        lookup[self.file_ids] = np.arange(self.n_vertices)
        return lookup

    def per_file_vertex(self, values: np.ndarray, fill) -> np.ndarray:
        """Spread per-internal-vertex values to per-file-vertex rows (dropped vertices get ``fill``)."""
        out = np.full((self.n_file_vertices,) + values.shape[1:], fill, dtype=values.dtype)
        out[self.file_ids] = values
        return out


def edge_keys(faces: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """One int64 key ``min * n + max`` per face-edge (3 per face), and the counts of each unique key."""
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    keys = e[:, 0] * n + e[:, 1]
    return keys, np.unique(keys, return_counts=True)[1]


def edge_weight_graph(n: int, edges: np.ndarray, weights: np.ndarray) -> sp.csr_matrix:
    i, j = edges[:, 0], edges[:, 1]
    return sp.csr_matrix((np.r_[weights, weights], (np.r_[i, j], np.r_[j, i])), shape=(n, n))


# ----------------------------------------------------------------------------------------------------------
# Building and validating


def build_mesh(vertices, faces, uv=None, *, name: str = "", texture_path: str | None = None) -> Mesh:
    """Validate raw arrays and build a :class:`Mesh`.

    ``faces`` may be an (f, 3) array or a list of polygons; polygons with more than three corners are
    triangulated as fans (counted in the report). Faces with fewer than three corners, indices out of range,
    non-finite coordinates and empty meshes are rejected. Degenerate faces (a repeated corner or zero area)
    are removed, then vertices no face uses are dropped with their ids remembered in ``file_ids``.
    Non-manifold edges, boundaries and several components are reported, not fatal.
    """
    report = MeshReport()
    vertices = _checked_vertices(vertices, name)
    n_file = len(vertices)
    tris = _triangulate(faces, report, name)
    _check_indices(tris, n_file, name)
    tris = _drop_degenerate(vertices, tris, report, name)
    used = np.unique(tris)
    file_ids = used.astype(np.int64)
    if len(used) < n_file:
        report.unreferenced_vertices_removed = n_file - len(used)
        report.warnings.append(
            f"{n_file - len(used)} vertices belong to no face and were dropped; file ids stay valid"
        )
        remap = np.full(n_file, -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        tris = remap[tris]
    if uv is not None:
        uv = np.asarray(uv, dtype=np.float64)[file_ids]
    mesh = Mesh(
        vertices=np.ascontiguousarray(vertices[file_ids]),
        faces=np.ascontiguousarray(tris, dtype=np.int64),
        file_ids=file_ids,
        n_file_vertices=n_file,
        report=report,
        uv=uv,
        texture_path=texture_path,
        name=name,
    )
    _note_topology(mesh, report)
    return mesh


def _checked_vertices(vertices, name: str) -> np.ndarray:
    try:
        v = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise CurvefmError(f"mesh '{name}': vertex coordinates are not numbers ({exc})") from None
    if v.size == 0:
        raise CurvefmError(f"mesh '{name}' is empty: it has no vertices")
    if v.ndim != 2 or v.shape[1] != 3:
        raise CurvefmError(f"mesh '{name}': vertices must be an (n, 3) array, got shape {v.shape}")
    if len(v) > max_vertices():
        raise CurvefmError(
            f"mesh '{name}' has {len(v)} vertices, more than the limit of {max_vertices()} "
            "(set CURVEFM_MAX_VERTICES to change it, or decimate the mesh)",
            kind="too_large",
        )
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise CurvefmError(
            f"mesh '{name}' has {int(bad.sum())} vertices with non-finite coordinates (NaN or inf), "
            f"the first is vertex {int(np.flatnonzero(bad)[0])}"
        )
    return v


def _triangulate(faces, report: MeshReport, name: str) -> np.ndarray:
    if not isinstance(faces, np.ndarray) and faces is not None and all(len(f) == 3 for f in faces):
        faces = np.array(faces, dtype=np.int64).reshape(-1, 3)
    if isinstance(faces, np.ndarray) and faces.ndim == 2 and faces.shape[1] == 3:
        tris = faces
    else:
        faces = list(faces) if faces is not None else []
        tris_list = []
        for index, poly in enumerate(faces):
            poly = list(poly)
            if len(poly) < 3:
                raise CurvefmError(
                    f"mesh '{name}': face {index} has {len(poly)} corners; faces need at least 3 "
                    "(lines and points are not surfaces)"
                )
            if len(poly) > 3:
                report.triangulated_polygons += 1
            tris_list.extend([poly[0], poly[i], poly[i + 1]] for i in range(1, len(poly) - 1))
        tris = np.array(tris_list).reshape(-1, 3)
    if len(tris) == 0:
        raise CurvefmError(f"mesh '{name}' has no faces; only triangle (or polygon) meshes are supported")
    if not np.issubdtype(np.asarray(tris).dtype, np.integer):
        raise CurvefmError(f"mesh '{name}': face indices must be integers")
    if report.triangulated_polygons:
        report.warnings.append(f"{report.triangulated_polygons} polygons were triangulated as fans")
    return np.asarray(tris, dtype=np.int64)


def _check_indices(tris: np.ndarray, n: int, name: str) -> None:
    bad = (tris < 0) | (tris >= n)
    if bad.any():
        face = int(np.flatnonzero(bad.any(axis=1))[0])
        raise CurvefmError(
            f"mesh '{name}': face {face} refers to vertex {int(tris[bad][0])}, but the mesh has {n} vertices "
            f"(valid ids are 0..{n - 1})"
        )


def _drop_degenerate(vertices: np.ndarray, tris: np.ndarray, report: MeshReport, name: str) -> np.ndarray:
    repeated = (tris[:, 0] == tris[:, 1]) | (tris[:, 1] == tris[:, 2]) | (tris[:, 0] == tris[:, 2])
    p = vertices[tris]
    doubled_area = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    scale = np.ptp(vertices, axis=0).max() if len(vertices) > 1 else 1.0
    flat = doubled_area <= 1e-14 * max(scale, 1e-300) ** 2
    degenerate = repeated | flat
    if degenerate.all():
        raise CurvefmError(f"mesh '{name}': all {len(tris)} faces are degenerate (zero area)")
    if degenerate.any():
        report.degenerate_faces_removed = int(degenerate.sum())
        report.warnings.append(f"{int(degenerate.sum())} degenerate faces (zero area) were removed")
    return tris[~degenerate]


def _note_topology(mesh: Mesh, report: MeshReport) -> None:
    _, counts = edge_keys(mesh.faces, mesh.n_vertices)
    report.non_manifold_edges = int((counts > 2).sum())
    report.boundary_edges = int((counts == 1).sum())
    report.components = int(connected_components(mesh.edge_graph, directed=False)[0])
    if report.non_manifold_edges:
        report.warnings.append(f"{report.non_manifold_edges} non-manifold edges (shared by 3+ faces)")
    if report.components > 1:
        report.warnings.append(
            f"{report.components} connected components: curves cannot cross between components"
        )


# ----------------------------------------------------------------------------------------------------------
# Files


def load_mesh(path: str | os.PathLike, name: str | None = None) -> Mesh:
    """Load a mesh, keeping the file's vertex order in every format.

    OBJ is read by our own parser because open3d's OBJ reader reorders vertices (by first use) and splits
    them at uv seams, which would silently break vertex ids and ground truth.
    """
    path = Path(path)
    name = name or path.stem
    suffix = path.suffix.lower()
    if not path.is_file():
        raise CurvefmError(f"mesh file not found: {path}", kind="not_found")
    if suffix not in SUPPORTED_FORMATS:
        raise CurvefmError(
            f"unsupported mesh format '{suffix}' for {path.name}; supported: {', '.join(SUPPORTED_FORMATS)}"
        )
    if suffix == ".obj":
        return _load_obj(path, name)
    if suffix == ".off":
        return _load_off(path, name)
    if suffix in GLTF_FORMATS:
        return _load_gltf(path, name)
    return _load_with_open3d(path, name)


def _load_with_open3d(path: Path, name: str) -> Mesh:
    import open3d as o3d

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    m = o3d.io.read_triangle_mesh(str(path), enable_post_processing=False)
    vertices = np.asarray(m.vertices)
    faces = np.asarray(m.triangles)
    if len(vertices) == 0:
        raise CurvefmError(f"could not read any vertices from {path.name}: the file is empty or malformed")
    if len(faces) == 0:
        raise CurvefmError(f"{path.name} has no faces; only triangle meshes are supported")
    uv = None
    if m.has_triangle_uvs():
        uv = _per_vertex_uv(faces, np.asarray(m.triangle_uvs).reshape(-1, 3, 2), len(vertices))
    if path.suffix.lower() == ".stl":
        vertices, faces = _weld(vertices, faces)
    return build_mesh(vertices, faces, uv, name=name)


def _weld(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """STL stores every triangle's corners separately and no vertex ids: merge equal positions, numbering
    vertices in order of first appearance in the file (the only order an STL file defines)."""
    unique, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return unique[order], rank[inverse.ravel()][faces]


def _load_gltf(path: Path, name: str) -> Mesh:
    # open3d's glTF reader (assimp) reorders vertices; trimesh with process=False keeps the buffer order
    import trimesh

    try:
        scene = trimesh.load(path, process=False, force="mesh")
    except Exception as exc:  # trimesh raises many types for broken files
        raise CurvefmError(f"could not read {path.name} as glTF: {exc}") from None
    uv = getattr(scene.visual, "uv", None)
    return build_mesh(np.asarray(scene.vertices), np.asarray(scene.faces), uv, name=name)


def _load_off(path: Path, name: str) -> Mesh:
    # read here rather than by open3d, whose OFF reader parses coordinates as float32
    lines = (line.split("#", 1)[0].split() for line in path.read_text(errors="replace").splitlines())
    tokens = [t for t in lines if t]
    if not tokens or not tokens[0][0].upper().endswith("OFF"):
        raise CurvefmError(f"{path.name} is not an OFF file: it does not start with 'OFF'")
    try:
        counts = tokens[0][1:] or tokens[1]
        n_vertices, n_faces = int(counts[0]), int(counts[1])
        body = tokens[1 if tokens[0][1:] else 2 :]
        if len(body) < n_vertices + n_faces:
            raise ValueError(f"header promises {n_vertices} vertices and {n_faces} faces, file is shorter")
        vertex_rows, face_rows = body[:n_vertices], body[n_vertices : n_vertices + n_faces]
        if any(len(row) < 3 for row in vertex_rows):
            raise ValueError("a vertex line has fewer than three coordinates")
        vertices = np.array([row[:3] for row in vertex_rows], dtype=np.float64)
        if any(len(row) < 1 + int(row[0]) for row in face_rows):
            raise ValueError("a face line lists fewer vertex ids than it declares")
        if all(row[0] == "3" for row in face_rows):  # the common all-triangle file: one array conversion
            faces = np.array([row[1:4] for row in face_rows], dtype=np.int64)
        else:
            faces = [[int(i) for i in row[1 : 1 + int(row[0])]] for row in face_rows]
    except (ValueError, IndexError) as exc:
        raise CurvefmError(f"{path.name} is not a valid OFF file: {exc}") from None
    return build_mesh(vertices, faces, name=name)


def _per_vertex_uv(faces: np.ndarray, corner_uv: np.ndarray, n: int) -> np.ndarray:
    """One uv per vertex from per-corner uvs; at a seam the first corner's value wins."""
    uv = np.full((n, 2), np.nan)
    flat_ids = faces.reshape(-1)[::-1]
    uv[flat_ids] = corner_uv.reshape(-1, 2)[::-1]  # reversed so the first occurrence is written last
    return np.nan_to_num(uv)


def _load_obj(path: Path, name: str) -> Mesh:
    vertices, texcoords, polys, poly_uv = [], [], [], []
    mtllib = None
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            for lineno, line in enumerate(f, 1):
                parts = line.split()
                if not parts:
                    continue
                tag = parts[0]
                if tag == "v":
                    vertices.append([float(x) for x in parts[1:4]])
                elif tag == "vt":
                    texcoords.append([float(x) for x in parts[1:3]])
                elif tag == "f":
                    corners = [c.split("/") for c in parts[1:]]
                    polys.append([_obj_index(c[0], len(vertices), lineno) for c in corners])
                    if all(len(c) > 1 and c[1] for c in corners):
                        poly_uv.append([_obj_index(c[1], len(texcoords), lineno) for c in corners])
                    else:
                        poly_uv.append(None)
                elif tag == "mtllib" and len(parts) > 1:
                    mtllib = path.parent / " ".join(parts[1:])
    except ValueError as exc:
        raise CurvefmError(f"{path.name} is not a valid OBJ file: {exc}") from None
    if not vertices:
        raise CurvefmError(f"could not read any vertices from {path.name}: the file is empty or malformed")
    uv = _obj_vertex_uv(len(vertices), polys, poly_uv, texcoords)
    return build_mesh(vertices, polys, uv, name=name, texture_path=_texture_from_mtl(mtllib))


def _obj_index(token: str, count: int, lineno: int) -> int:
    index = int(token)
    return index - 1 if index > 0 else count + index  # OBJ is 1-based; negative counts from the end


def _obj_vertex_uv(n: int, polys, poly_uv, texcoords) -> np.ndarray | None:
    if not texcoords or any(p is None for p in poly_uv):
        return None
    tc = np.asarray(texcoords)
    corner_v = np.concatenate([np.asarray(p) for p in polys])
    corner_t = np.concatenate([np.asarray(p) for p in poly_uv])
    if corner_t.max() >= len(tc) or corner_t.min() < 0:
        raise CurvefmError("OBJ face refers to a texture coordinate that does not exist")
    return _per_vertex_uv(corner_v, tc[corner_t], n)


def _texture_from_mtl(mtllib: Path | None) -> str | None:
    if mtllib is None or not mtllib.is_file():
        return None
    for line in mtllib.read_text(errors="replace").splitlines():
        parts = line.split()
        if parts and parts[0] == "map_Kd" and len(parts) > 1:
            image = mtllib.parent / parts[-1]
            return str(image) if image.is_file() else None
    return None


def save_mesh(mesh: Mesh, path: str | os.PathLike, uv: np.ndarray | None = None) -> None:
    """Write a mesh. OBJ is written by us (with ``uv`` or the mesh's own uv as ``vt``); other formats by open3d."""
    path = Path(path)
    suffix = path.suffix.lower()
    uv = mesh.uv if uv is None else uv
    if suffix == ".obj":
        _save_obj(mesh, path, uv)
        return
    if suffix == ".off":
        _save_off(mesh, path)
        return
    if suffix not in OPEN3D_FORMATS:
        raise CurvefmError(f"cannot write format '{suffix}'; supported: {', '.join(SUPPORTED_FORMATS)}")
    import open3d as o3d

    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(mesh.vertices), o3d.utility.Vector3iVector(mesh.faces))
    if suffix == ".stl":
        m.compute_triangle_normals()
    if not o3d.io.write_triangle_mesh(str(path), m):
        raise CurvefmError(f"could not write {path}")


def _save_off(mesh: Mesh, path: Path) -> None:
    # written here rather than by open3d, whose OFF writer rounds coordinates to 7 digits
    with open(path, "w") as f:
        f.write(f"OFF\n{mesh.n_vertices} {len(mesh.faces)} 0\n")
        np.savetxt(f, mesh.vertices, fmt="%.17g")
        np.savetxt(f, mesh.faces, fmt="3 %d %d %d")


def _save_obj(mesh: Mesh, path: Path, uv: np.ndarray | None) -> None:
    with open(path, "w") as f:
        f.write(f"# written by curvefm: {mesh.n_vertices} vertices, {len(mesh.faces)} faces\n")
        np.savetxt(f, mesh.vertices, fmt="v %.17g %.17g %.17g")
        faces = mesh.faces + 1
        if uv is not None:
            np.savetxt(f, uv, fmt="vt %.9g %.9g")
            np.savetxt(f, np.repeat(faces, 2, axis=1), fmt="f %d/%d %d/%d %d/%d")
        else:
            np.savetxt(f, faces, fmt="f %d %d %d")
