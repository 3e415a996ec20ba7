"""Evaluation of pointwise maps: geodesic error (Princeton-benchmark style) and ground-truth readers.

Conventions
-----------
- A pointwise map ``p2p_XY`` is an integer array with one entry per vertex of X: ``p2p_XY[i]`` is the vertex
  of Y that vertex ``i`` of X is sent to. All ids here are *internal* mesh ids (see :mod:`curvefm.mesh`).
- Ground truth is a pair of equal-length arrays ``(ids_X, ids_Y)``: vertex ``ids_X[r]`` of X corresponds to
  vertex ``ids_Y[r]`` of Y. A vertex may appear in several rows (e.g. a many-to-one dense map).
- The error of a map X -> Y is measured **on Y**: for each row r, the geodesic distance on Y between the
  predicted partner ``p2p_XY[ids_X[r]]`` and the true partner ``ids_Y[r]``, divided by Y's geodesic diameter
  (the Princeton-benchmark normalisation, used for the cumulative curve) and, separately, by sqrt(area of Y).

Geodesic distances
------------------
Distances are shortest paths in a graph on the mesh vertices (:func:`geodesic_graph`): the mesh edges
weighted by their Euclidean length, plus, for every interior manifold edge whose two triangles form a convex
quadrilateral, the "diagonal" joining the two opposite vertices, weighted by the straight-line length in the
plane where the two triangles are unfolded (a true geodesic inside the surface). Measured against analytic
distances (points farther than 0.2x the maximum from the source; see ``tests/test_evaluation.py``):

==============================  =======================  ======================
shape                           edges only: mean / max   with diagonals
==============================  =======================  ======================
jittered Delaunay plane, 2.5k   5.5% / 11.1%             1.7% / 5.5%
sphere, 3k vertices             8.7% / 12.0%             1.6% / 3.4%
regular grid, same diagonal     17.4% / 41.4%            3.3% / 8.2%
==============================  =======================  ======================

The graph never underestimates the polyhedral geodesic (every graph edge is a path on the surface). The
diagonals double the edge count, so each Dijkstra costs about 1.6x more. Pass ``diagonals=False`` for
plain edge Dijkstra.

Pair distances (:func:`pair_geodesic_distances`) run ``scipy.sparse.csgraph.dijkstra`` from as few sources as
possible (a greedy vertex cover of the pairs), in chunks whose output stays below a memory bound, and with a
growing search radius (``limit``) that starts just above the Euclidean distance to the farthest partner of
each source, so that accurate maps (short errors) only explore small balls. The cost therefore grows with
the errors: on FAUST (6890 vertices, all of them evaluated) a perfect map takes milliseconds, a
nearest-neighbour map about 1 s, a half left/right-flipped map 2-3 s and a uniformly random map 10-12 s
(about 3400 full Dijkstra runs); subsample the ground-truth rows for quick estimates of bad maps.

The geodesic diameter (:func:`geodesic_diameter`) is an iterated double sweep: Dijkstra from a vertex, then
from the farthest vertex found, until the eccentricity stops growing. It is a lower bound on the graph
diameter; on FAUST tr_reg_001, TOSCA wolf0 and pyFM cat-00 it equals the maximum over all-pairs distances.
"""

from __future__ import annotations

import os
import re
import weakref
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from curvefm.errors import CurvefmError
from curvefm.mesh import Mesh, load_mesh

# Radii of the cumulative error curve, as fractions of the target's geodesic diameter.
CURVE_RADII = np.linspace(0.0, 0.25, 51)

# Bytes of Dijkstra output (chunk of sources x n float64) held at once.
DEFAULT_CHUNK_BYTES = 64 * 2**20

_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _cache(mesh: Mesh) -> dict:
    try:
        return _CACHE.setdefault(mesh, {})
    except TypeError:  # not weak-referenceable: no caching
        return {}


# ----------------------------------------------------------------------------------------------------------
# Geodesic graph, distances, diameter


def geodesic_graph(mesh: Mesh, diagonals: bool = True) -> sp.csr_matrix:
    """Symmetric sparse graph whose shortest paths approximate geodesic distances on ``mesh``.

    With ``diagonals=False`` this is :attr:`Mesh.edge_graph` (edges weighted by Euclidean length). With
    ``diagonals=True`` (default) every interior manifold edge (i, j) with triangles (i, j, k) and (j, i, l)
    also contributes the edge (k, l), weighted by the length of the straight segment k-l in the plane where
    both triangles are unfolded, when that segment crosses the edge (i, j) (convex quadrilateral); otherwise
    the shortest path inside the two triangles goes through i or j and is already in the graph. Every added
    weight is the length of a path on the surface, so graph distances never underestimate polyhedral
    geodesics. The graph is cached per mesh object.
    """
    cache = _cache(mesh)
    key = ("graph", bool(diagonals))
    if key in cache:
        return cache[key]
    if not diagonals:
        graph = mesh.edge_graph
    else:
        k, opp, length = _unfolded_diagonals(mesh)
        edges = np.r_[mesh.edges, np.c_[np.minimum(k, opp), np.maximum(k, opp)]]
        weights = np.r_[mesh.edge_lengths, length]
        graph = _min_weight_graph(mesh.n_vertices, edges, weights)
    cache[key] = graph
    return graph


def _unfolded_diagonals(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    faces, v = mesh.faces, mesh.vertices
    a = faces.ravel()
    b = faces[:, [1, 2, 0]].ravel()
    c = faces[:, [2, 0, 1]].ravel()  # corner opposite the half-edge (a, b)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    order = np.lexsort((hi, lo))
    lo, hi, c = lo[order], hi[order], c[order]
    same = (lo[1:] == lo[:-1]) & (hi[1:] == hi[:-1])
    first = np.flatnonzero(same)
    # keep edges that occur exactly twice (interior manifold edges)
    before = np.r_[False, same[:-1]][first]
    after = np.r_[same[1:], False][first]
    first = first[~before & ~after]
    i, j, k, m = lo[first], hi[first], c[first], c[first + 1]  # k, m: the two opposite corners
    e = v[j] - v[i]
    length_e = np.linalg.norm(e, axis=1)
    u = e / length_e[:, None]
    dk, dl = v[k] - v[i], v[m] - v[i]
    xk = np.einsum("ij,ij->i", dk, u)
    xl = np.einsum("ij,ij->i", dl, u)
    yk = np.linalg.norm(dk - xk[:, None] * u, axis=1)
    yl = np.linalg.norm(dl - xl[:, None] * u, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cross_x = xk + (xl - xk) * yk / (yk + yl)  # where the unfolded segment k-l meets line (i, j)
    ok = (k != m) & (yk > 0) & (yl > 0) & (cross_x > 0) & (cross_x < length_e)
    return k[ok], m[ok], np.hypot(xk - xl, yk + yl)[ok]


def _min_weight_graph(n: int, edges: np.ndarray, weights: np.ndarray) -> sp.csr_matrix:
    """Symmetric csr graph; for repeated edges the smallest weight wins (csr would add them)."""
    order = np.lexsort((weights, edges[:, 1], edges[:, 0]))
    edges, weights = edges[order], weights[order]
    keep = np.r_[True, (np.diff(edges, axis=0) != 0).any(axis=1)]
    edges, weights = edges[keep], weights[keep]
    i, j = edges[:, 0], edges[:, 1]
    return sp.csr_matrix((np.r_[weights, weights], (np.r_[i, j], np.r_[j, i])), shape=(n, n))


def geodesic_distances(mesh: Mesh, sources, *, diagonals: bool = True) -> np.ndarray:
    """Graph-geodesic distances from each of ``sources`` (internal ids) to every vertex: (len(sources), n).

    The full matrix is returned, so keep ``sources`` small on large meshes (or use
    :func:`pair_geodesic_distances`). Unreachable vertices (another component) get ``inf``.
    """
    sources = _checked_ids(sources, mesh.n_vertices, "source vertex")
    graph = geodesic_graph(mesh, diagonals)
    return np.atleast_2d(dijkstra(graph, directed=True, indices=sources))


def geodesic_diameter(mesh: Mesh, *, diagonals: bool = True, max_sweeps: int = 6) -> float:
    """Geodesic diameter of ``mesh`` by iterated double sweep (cached per mesh object).

    Starts at the vertex farthest (Euclidean) from the centroid, runs Dijkstra from the farthest vertex
    found so far until the eccentricity stops growing (at most ``max_sweeps`` runs). This is a lower bound
    of the graph diameter, exact on most shapes. On a mesh with several components it is the diameter of
    the component of the starting vertex.
    """
    cache = _cache(mesh)
    key = ("diameter", bool(diagonals))
    if key in cache:
        return cache[key]
    graph = geodesic_graph(mesh, diagonals)
    start = int(np.argmax(np.linalg.norm(mesh.vertices - mesh.vertices.mean(axis=0), axis=1)))
    best = 0.0
    seen = set()
    for _ in range(max_sweeps):
        seen.add(start)
        d = dijkstra(graph, directed=True, indices=start)
        d[~np.isfinite(d)] = -1.0
        far = int(np.argmax(d))
        if d[far] <= best * (1 + 1e-12) and best > 0:
            break
        best = float(d[far])
        if far in seen:
            break
        start = far
    cache[key] = best
    return best


def pair_geodesic_distances(
    mesh: Mesh,
    a,
    b,
    *,
    diagonals: bool = True,
    chunk_bytes: int = DEFAULT_CHUNK_BYTES,
) -> np.ndarray:
    """Graph-geodesic distance between ``a[r]`` and ``b[r]`` on ``mesh`` for every row r (internal ids).

    Runs Dijkstra from a small set of sources covering every pair (greedy vertex cover: for a map against
    the identity this is about half the vertices, not all of them), ``chunk_bytes`` of output at a time,
    with a search radius that starts at 1.3x the Euclidean distance to the source's farthest partner and
    doubles for the pairs not reached (unbounded after three tries). Unreachable pairs get ``inf``.
    """
    n = mesh.n_vertices
    a = _checked_ids(a, n, "vertex")
    b = _checked_ids(b, n, "vertex")
    if a.shape != b.shape:
        raise CurvefmError(
            f"pair_geodesic_distances needs equally many ids on both sides, got {a.size} and {b.size}"
        )
    out = np.zeros(a.shape, dtype=np.float64)
    todo = np.flatnonzero(a != b)
    if todo.size == 0:
        return out
    graph = geodesic_graph(mesh, diagonals)
    src, dst, row = _cover_pairs(a[todo], b[todo])
    row = todo[row]
    # Euclidean distance is a lower bound of the geodesic: start the search just beyond it.
    euclid = np.linalg.norm(mesh.vertices[src] - mesh.vertices[dst], axis=1)
    slack = 2.0 * float(np.mean(mesh.edge_lengths))
    sources, inverse = np.unique(src, return_inverse=True)
    need = np.zeros(len(sources))
    np.maximum.at(need, inverse, euclid)
    limit = 1.3 * need + slack
    pending = np.ones(len(src), dtype=bool)
    rows_per_chunk = max(1, int(chunk_bytes // (8 * n)))
    for attempt in range(4):
        active = np.unique(inverse[pending])
        if active.size == 0:
            break
        active = active[np.argsort(limit[active], kind="stable")]
        for start in range(0, active.size, rows_per_chunk):
            chunk = active[start : start + rows_per_chunk]
            chunk_limit = np.inf if attempt == 3 else float(limit[chunk].max())
            d = np.atleast_2d(dijkstra(graph, directed=True, indices=sources[chunk], limit=chunk_limit))
            position = np.full(len(sources), -1)
            position[chunk] = np.arange(chunk.size)
            sel = np.flatnonzero(pending & (position[inverse] >= 0))
            values = d[position[inverse[sel]], dst[sel]]
            found = np.isfinite(values) | (attempt == 3)
            out[row[sel[found]]] = values[found]
            pending[sel[found]] = False
        limit = 2.0 * limit
    return out


def _cover_pairs(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orient each pair (a[r], b[r]) as (source, target) so that few distinct sources cover all pairs.

    Greedy vertex cover in order of decreasing degree. Returns (source, target, r) for every pair.
    """
    m = a.size
    n = int(max(a.max(), b.max())) + 1
    ends = np.r_[a, b]
    pair_of_end = np.r_[np.arange(m), np.arange(m)]
    degree = np.bincount(ends, minlength=n)
    order = np.lexsort((ends, -degree[ends]))  # ends grouped by vertex, high degree first
    ends, pair_of_end = ends[order], pair_of_end[order]
    covered = np.zeros(m, dtype=bool)
    source = np.empty(m, dtype=np.int64)
    boundaries = np.flatnonzero(np.r_[True, ends[1:] != ends[:-1], True])
    for lo, hi in zip(boundaries[:-1], boundaries[1:], strict=False):
        pairs = pair_of_end[lo:hi]
        new = pairs[~covered[pairs]]
        if new.size:
            covered[new] = True
            source[new] = ends[lo]
    target = np.where(source == a, b, a)
    return source, target, np.arange(m)


def _checked_ids(ids, n: int, what: str) -> np.ndarray:
    ids = np.asarray(ids)
    if ids.size and not np.issubdtype(ids.dtype, np.integer):
        raise CurvefmError(f"{what} ids must be integers, got dtype {ids.dtype}")
    ids = ids.astype(np.int64).reshape(-1)
    bad = (ids < 0) | (ids >= n)
    if bad.any():
        raise CurvefmError(f"{what} id {int(ids[bad][0])} is out of range: valid internal ids are 0..{n - 1}")
    return ids


# ----------------------------------------------------------------------------------------------------------
# Farthest point sampling


def farthest_point_sampling(
    mesh: Mesh, count: int, seed_vertex: int = 0, *, diagonals: bool = True
) -> np.ndarray:
    """``count`` well-spread vertices (internal ids) by farthest-point sampling with graph geodesics.

    The first sample is ``seed_vertex``; each next one is the vertex farthest from all samples so far.
    Each Dijkstra is limited to the current covering radius (nothing farther can change), so the cost
    shrinks as the samples densify. Vertices of other components are reached first (infinite distance).
    """
    n = mesh.n_vertices
    if not 1 <= int(count) <= n:
        raise CurvefmError(
            f"farthest_point_sampling: count must be between 1 and {n} (the vertex count), got {count}"
        )
    seed = int(_checked_ids([seed_vertex], n, "seed vertex")[0])
    graph = geodesic_graph(mesh, diagonals)
    samples = np.empty(int(count), dtype=np.int64)
    samples[0] = seed
    nearest = np.full(n, np.inf)
    for s in range(int(count)):
        if s > 0:
            samples[s] = int(np.argmax(nearest))
        radius = float(nearest.max())
        d = dijkstra(graph, directed=True, indices=int(samples[s]), limit=radius)
        np.minimum(nearest, d, out=nearest)
    return samples


# ----------------------------------------------------------------------------------------------------------
# Error summary


@dataclass
class ErrorSummary:
    """Geodesic errors of a pointwise map, measured on the target mesh.

    ``mean``/``median``/``max`` are divided by the target's geodesic diameter; ``mean_area``/``median_area``
    by sqrt(area of the target). ``curve[i]`` is the fraction of correspondences whose error (by diameter)
    is at most ``radii[i]`` (``radii`` = linspace(0, 0.25, 51)); ``auc`` is the normalised area under that
    curve (1 = every error is 0). ``count`` is the number of correspondences evaluated.
    """

    count: int
    mean: float
    median: float
    max: float
    mean_area: float
    median_area: float
    auc: float
    diameter: float
    sqrt_area: float
    radii: np.ndarray = field(repr=False)
    curve: np.ndarray = field(repr=False)
    distances: str = "dijkstra+unfolded-diagonals"

    @classmethod
    def from_distances(
        cls, distances: np.ndarray, diameter: float, area: float, method: str = "dijkstra+unfolded-diagonals"
    ) -> ErrorSummary:
        """Summarise raw geodesic errors (in the target's units)."""
        d = np.asarray(distances, dtype=np.float64).reshape(-1)
        if d.size == 0:
            raise CurvefmError("no correspondences to evaluate: the ground truth is empty")
        if not diameter > 0 or not area > 0:
            raise CurvefmError("cannot normalise errors: the target mesh has zero diameter or area")
        by_diam = d / diameter
        sqrt_area = float(np.sqrt(area))
        curve = (by_diam[None, :] <= CURVE_RADII[:, None] + 1e-12).mean(axis=1)
        auc = float(np.sum((curve[1:] + curve[:-1]) * np.diff(CURVE_RADII)) / 2 / CURVE_RADII[-1])
        return cls(
            count=int(d.size),
            mean=float(by_diam.mean()),
            median=float(np.median(by_diam)),
            max=float(by_diam.max()),
            mean_area=float(d.mean() / sqrt_area),
            median_area=float(np.median(d) / sqrt_area),
            auc=auc,
            diameter=float(diameter),
            sqrt_area=sqrt_area,
            radii=CURVE_RADII.copy(),
            curve=curve,
            distances=method,
        )

    def as_dict(self) -> dict:
        """Plain JSON-ready dict (lists for the curve; inf errors become None)."""

        def num(x: float):
            return float(x) if np.isfinite(x) else None

        return {
            "count": self.count,
            "mean": num(self.mean),
            "median": num(self.median),
            "max": num(self.max),
            "mean_area": num(self.mean_area),
            "median_area": num(self.median_area),
            "auc": num(self.auc),
            "diameter": self.diameter,
            "sqrt_area": self.sqrt_area,
            "normalisation": "mean/median/max/curve by geodesic diameter; *_area by sqrt(area); target mesh",
            "distances": self.distances,
            "radii": [float(r) for r in self.radii],
            "curve": [float(c) for c in self.curve],
        }


def _truth_arrays(truth) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(truth, np.ndarray) and truth.ndim == 2 and truth.shape[1] == 2:
        return truth[:, 0], truth[:, 1]
    try:
        ids_x, ids_y = truth
    except (TypeError, ValueError):
        raise CurvefmError(
            "ground truth must be a pair (ids_X, ids_Y) of equal-length id arrays or an (m, 2) array"
        ) from None
    ids_x, ids_y = np.asarray(ids_x).reshape(-1), np.asarray(ids_y).reshape(-1)
    if ids_x.shape != ids_y.shape:
        raise CurvefmError(f"ground truth sides differ in length: {ids_x.size} ids on X, {ids_y.size} on Y")
    return ids_x, ids_y


def map_geodesic_errors(p2p_XY, truth, mesh_Y: Mesh, *, diagonals: bool = True) -> np.ndarray:
    """Raw geodesic errors on Y (in Y's units), one per ground-truth row.

    ``p2p_XY[i]`` is the vertex of Y for vertex i of X (internal ids); ``truth`` is ``(ids_X, ids_Y)``
    (internal ids: vertex ids_X[r] of X corresponds to ids_Y[r] of Y) or an (m, 2) array of such rows.
    """
    p2p = np.asarray(p2p_XY)
    if p2p.ndim != 1:
        raise CurvefmError(
            f"a pointwise map must be a 1-D array (one Y vertex per X vertex), got shape {p2p.shape}"
        )
    ids_x, ids_y = _truth_arrays(truth)
    ids_x = _checked_ids(ids_x, len(p2p), "ground-truth source (X) vertex")
    ids_y = _checked_ids(ids_y, mesh_Y.n_vertices, "ground-truth target (Y) vertex")
    predicted = _checked_ids(p2p, mesh_Y.n_vertices, "mapped (Y) vertex")[ids_x]
    return pair_geodesic_distances(mesh_Y, predicted, ids_y, diagonals=diagonals)


def evaluate_map(p2p_XY, truth, mesh_Y: Mesh, *, diagonals: bool = True) -> ErrorSummary:
    """Princeton-benchmark geodesic error of the map X -> Y, measured on Y.

    Parameters
    ----------
    p2p_XY : (n_X,) int array
        ``p2p_XY[i]`` is the vertex of Y (internal id) that vertex i of X is mapped to.
    truth : (ids_X, ids_Y) or (m, 2) array or :class:`GroundTruth`
        Internal ids; vertex ``ids_X[r]`` of X truly corresponds to vertex ``ids_Y[r]`` of Y.
    mesh_Y : Mesh
        The target, on which distances are measured and by whose diameter / sqrt(area) they are divided.
    """
    errors = map_geodesic_errors(p2p_XY, truth, mesh_Y, diagonals=diagonals)
    method = "dijkstra+unfolded-diagonals" if diagonals else "dijkstra-edges"
    return ErrorSummary.from_distances(
        errors, geodesic_diameter(mesh_Y, diagonals=diagonals), mesh_Y.area, method
    )


# ----------------------------------------------------------------------------------------------------------
# Ground truth


@dataclass(frozen=True)
class GroundTruth:
    """Known correspondences between X and Y in internal ids: vertex ids_X[r] of X <-> ids_Y[r] of Y.

    Unpacks like a tuple: ``ids_X, ids_Y = ground_truth_for(...)``. ``kind`` says where it came from
    (``identity``, ``faust5k-vts``, ``faust5k-sampleid``, ``tosca-landmarks``, ``lion2cat``,
    ``cat-lion-landmarks``); ``dense`` is False for sparse landmark sets.
    """

    ids_X: np.ndarray
    ids_Y: np.ndarray
    kind: str
    dense: bool

    def __iter__(self):
        return iter((self.ids_X, self.ids_Y))

    def __len__(self) -> int:
        return int(self.ids_X.size)


def shared_data_dir() -> Path:
    """The shared data folder: ``$CURVEFM_SHARED_DATA`` or ``<repo>/../shared/data``; error if absent."""
    env = os.environ.get("CURVEFM_SHARED_DATA")
    path = Path(env) if env else Path(__file__).resolve().parents[1].parent / "shared" / "data"
    if not path.is_dir():
        raise CurvefmError(
            f"shared data folder not found at {path}: set CURVEFM_SHARED_DATA to the folder with the "
            "benchmark meshes (faust/, tosca/, ...) or put it at ../shared/data next to the project checkout",
            kind="not_found",
        )
    return path


def _read_int_column(path: Path, column: int = 0, what: str = "ids") -> np.ndarray:
    path = Path(path)
    if not path.is_file():
        raise CurvefmError(f"ground-truth file not found: {path}", kind="not_found")
    try:
        data = np.loadtxt(path, ndmin=2)
    except ValueError as exc:
        raise CurvefmError(f"{path.name} is not a table of numbers ({exc})") from None
    if data.shape[1] <= column:
        raise CurvefmError(
            f"{path.name} has {data.shape[1]} columns; expected at least {column + 1} ({what})"
        )
    values = data[:, column]
    if not np.all(values == np.round(values)):
        raise CurvefmError(f"{path.name}: {what} must be integers")
    return values.astype(np.int64)


def read_vts(path) -> np.ndarray:
    """Read a ``.vts`` correspondence file (1-based vertex ids, first column) as 0-based file ids."""
    ids = _read_int_column(path, 0, "1-based vertex ids") - 1
    if ids.size and ids.min() < 0:
        raise CurvefmError(f"{Path(path).name} contains id 0 or a negative id; .vts files are 1-based")
    return ids


def read_pid(path) -> np.ndarray:
    """Read a TOSCA/SCB ``.pid`` landmark file (lines ``vid 0 0 0``, 0-based) as 0-based file ids."""
    return _read_int_column(path, 0, "0-based landmark vertex ids")


def identity_truth(mesh_X: Mesh, mesh_Y: Mesh) -> GroundTruth:
    """Vertex i of the X file <-> vertex i of the Y file (same vertex count and ordering)."""
    if mesh_X.n_file_vertices != mesh_Y.n_file_vertices:
        raise CurvefmError(
            f"identity ground truth needs equal vertex counts, but '{mesh_X.name}' has "
            f"{mesh_X.n_file_vertices} and '{mesh_Y.name}' has {mesh_Y.n_file_vertices} vertices"
        )
    common = np.intersect1d(mesh_X.file_ids, mesh_Y.file_ids)
    return GroundTruth(mesh_X.internal_ids(common), mesh_Y.internal_ids(common), "identity", True)


def file_pairs_truth(
    mesh_X: Mesh, mesh_Y: Mesh, file_ids_X, file_ids_Y, kind: str, dense: bool
) -> GroundTruth:
    """Ground truth from 0-based *file* ids (row r <-> row r), translated to internal ids."""
    fx, fy = np.asarray(file_ids_X).reshape(-1), np.asarray(file_ids_Y).reshape(-1)
    if fx.size != fy.size:
        raise CurvefmError(
            f"ground truth rows differ: {fx.size} for '{mesh_X.name}', {fy.size} for '{mesh_Y.name}'"
        )
    return GroundTruth(
        mesh_X.internal_ids(fx, f"ground-truth vertex of '{mesh_X.name}'"),
        mesh_Y.internal_ids(fy, f"ground-truth vertex of '{mesh_Y.name}'"),
        kind,
        dense,
    )


def faust5k_truth(path_X, path_Y, mesh_X: Mesh, mesh_Y: Mesh, *, symmetric: bool = False) -> GroundTruth:
    """FAUST-5k (BCICP) ground truth from ``corres/NAME.vts``: row r of X's file <-> row r of Y's file.

    With ``symmetric=True`` Y's ``NAME.sym.vts`` is used (the left/right-swapped correspondence).
    """
    px, py = Path(path_X), Path(path_Y)
    vx = read_vts(px.parent / "corres" / f"{px.stem}.vts")
    vy = read_vts(py.parent / "corres" / f"{py.stem}{'.sym' if symmetric else ''}.vts")
    return file_pairs_truth(mesh_X, mesh_Y, vx, vy, "faust5k-vts" + ("-sym" if symmetric else ""), True)


def tosca_class(path) -> str:
    """TOSCA class of a mesh file: the stem without trailing digits (``horse5.off`` -> ``horse``)."""
    return re.sub(r"\d+$", "", Path(path).stem)


def tosca_landmark_truth(path_X, path_Y, mesh_X: Mesh, mesh_Y: Mesh) -> GroundTruth:
    """TOSCA sparse semantic landmarks: row r of ``Corrs/CLASS_X.pid`` <-> row r of ``Corrs/CLASS_Y.pid``.

    Only classes with the same landmark definitions match: animals (cat, dog, horse, wolf, 21 landmarks),
    humans (david, michael, victoria, gorilla, 36), centaur (46, only with itself).
    """
    px, py = Path(path_X), Path(path_Y)
    cx, cy = tosca_class(px), tosca_class(py)
    lx = read_pid(px.parent / "Corrs" / f"{cx}.pid")
    ly = read_pid(py.parent / "Corrs" / f"{cy}.pid")
    _check_tosca_compatible(cx, cy)
    if lx.size != ly.size:
        raise CurvefmError(f"TOSCA landmark files disagree: {cx}.pid has {lx.size} rows, {cy}.pid {ly.size}")
    return file_pairs_truth(mesh_X, mesh_Y, lx, ly, "tosca-landmarks", False)


def _check_tosca_compatible(cx: str, cy: str) -> None:
    if cx not in _TOSCA_GROUP or cy not in _TOSCA_GROUP or _TOSCA_GROUP[cx] != _TOSCA_GROUP[cy]:
        raise CurvefmError(
            f"no landmark ground truth between TOSCA classes '{cx}' and '{cy}': landmarks match only within "
            "animals (cat, dog, horse, wolf), humans (david, michael, victoria, gorilla) or centaur"
        )


_TOSCA_GROUP = {
    "cat": "animal", "dog": "animal", "horse": "animal", "wolf": "animal",
    "david": "human", "michael": "human", "victoria": "human", "gorilla": "human",
    "centaur": "centaur",
}  # fmt: skip


def read_lion2cat(path) -> np.ndarray:
    """pyFM's ``lion2cat``: one row per lion vertex, the 0-based cat vertex (a map lion -> cat)."""
    return _read_int_column(path, 0, "0-based cat vertex ids")


def cat_lion_truth(path_X, path_Y, mesh_X: Mesh, mesh_Y: Mesh, *, dense: bool = True) -> GroundTruth:
    """pyFM cat <-> lion ground truth, in either direction.

    ``dense=True``: ``lion2cat`` (lion vertex r <-> cat vertex lion2cat[r], 5000 rows; approximate, and
    many-to-one on the cat side). ``dense=False``: the 20 ``landmarks.txt`` rows (``cat_vid lion_vid``).
    """
    px, py = Path(path_X), Path(path_Y)
    folder = px.parent
    roles = {px.stem.split("-")[0]: "X", py.stem.split("-")[0]: "Y"}
    if set(roles) != {"cat", "lion"}:
        raise CurvefmError(
            f"cat/lion ground truth needs one cat and one lion mesh, got {px.name} and {py.name}"
        )
    if dense:
        cat = read_lion2cat(folder / "lion2cat")
        lion = np.arange(cat.size)
        kind = "lion2cat"
    else:
        table = np.c_[
            _read_int_column(folder / "landmarks.txt", 0), _read_int_column(folder / "landmarks.txt", 1)
        ]
        cat, lion = table[:, 0], table[:, 1]
        kind = "cat-lion-landmarks"
    if roles["cat"] == "X":
        return file_pairs_truth(mesh_X, mesh_Y, cat, lion, kind, dense)
    return file_pairs_truth(mesh_X, mesh_Y, lion, cat, kind, dense)


def _faust5k_to_full(path_5k: Path, mesh_5k: Mesh, mesh_full: Mesh, five_k_is_x: bool) -> GroundTruth:
    rows = read_vts(path_5k.parent / "corres" / f"{path_5k.stem}.vts")
    full = read_vts(path_5k.parent / "corres" / "sampleID.vts")
    if five_k_is_x:
        return file_pairs_truth(mesh_5k, mesh_full, rows, full, "faust5k-sampleid", True)
    return file_pairs_truth(mesh_full, mesh_5k, full, rows, "faust5k-sampleid", True)


def ground_truth_for(
    path_X, path_Y, mesh_X: Mesh | None = None, mesh_Y: Mesh | None = None, *, dense: bool = True
) -> GroundTruth:
    """Pick and read the known ground truth between two meshes of the shared data folder.

    The dataset is recognised from the folder each file lies in (as laid out in the shared data README):

    - ``faust/`` <-> ``faust/``: identity (6890 rows).
    - ``faust_5k_bcicp/`` <-> ``faust_5k_bcicp/``: ``corres/NAME.vts`` rows (5000, 1-based in the file).
    - ``faust_5k_bcicp/`` <-> ``faust/``: ``NAME.vts`` row r <-> ``sampleID.vts`` row r.
    - ``tosca/``: identity within a class (e.g. cat0 <-> cat2); landmarks ``Corrs/CLASS.pid`` across
      compatible classes (e.g. horse <-> cat, david <-> gorilla), or within a class with ``dense=False``.
    - ``pyfm_cat_lion/``: ``lion2cat`` (``dense=True``) or ``landmarks.txt`` (``dense=False``).
    - ``ogre/`` (``bs_rest`` <-> ``bs_smile``): identity.

    Returns a :class:`GroundTruth` in internal ids (unpacks as ``ids_X, ids_Y``). Meshes are loaded from the
    paths when not given. Raises :class:`CurvefmError` when no ground truth is known for the pair.
    """
    px, py = Path(path_X), Path(path_Y)
    for p in (px, py):
        if not p.is_file():
            raise CurvefmError(f"mesh file not found: {p}", kind="not_found")
    reader = _truth_reader(px, py, dense)  # decided (and refused) from the paths, before loading meshes
    mesh_X = mesh_X if mesh_X is not None else load_mesh(px)
    mesh_Y = mesh_Y if mesh_Y is not None else load_mesh(py)
    return reader(mesh_X, mesh_Y)


def _truth_reader(px: Path, py: Path, dense: bool):
    fx, fy = px.resolve().parent.name, py.resolve().parent.name
    if fx == fy == "faust":
        return identity_truth
    if fx == fy == "faust_5k_bcicp":
        return lambda mx, my: faust5k_truth(px, py, mx, my)
    if {fx, fy} == {"faust", "faust_5k_bcicp"}:
        if fx == "faust_5k_bcicp":
            return lambda mx, my: _faust5k_to_full(px, mx, my, five_k_is_x=True)
        return lambda mx, my: _faust5k_to_full(py, my, mx, five_k_is_x=False)
    if fx == fy == "tosca":
        if tosca_class(px) == tosca_class(py) and dense:
            return identity_truth
        _check_tosca_compatible(tosca_class(px), tosca_class(py))
        return lambda mx, my: tosca_landmark_truth(px, py, mx, my)
    if fx == fy == "pyfm_cat_lion" and {px.stem.split("-")[0], py.stem.split("-")[0]} == {"cat", "lion"}:
        return lambda mx, my: cat_lion_truth(px, py, mx, my, dense=dense)
    if fx == fy == "ogre" and {px.stem, py.stem} <= {"bs_rest", "bs_smile"}:
        return identity_truth
    raise CurvefmError(
        f"no known ground truth between {px} and {py}: supported pairs are faust/*, faust_5k_bcicp/* (with "
        "each other or with faust/), tosca/* (same class, or compatible classes via landmarks), "
        "pyfm_cat_lion cat <-> lion and ogre bs_rest <-> bs_smile, as laid out in the shared data folder"
    )
