"""Tracer plugins: a vertex path on the mesh's edge graph between two clicked vertices.

Both tracers return ``path`` (int64 **internal** vertex ids, ``path[0] == start``, ``path[-1] == end``,
consecutive entries share a mesh edge) and run Dijkstra on a weighted edge graph, from both ends at once, each
search bounded by a reach that grows until they meet on a provably shortest path (see ``_trace``).

``geodesic``
    Edge weights are Euclidean edge lengths (``mesh.edge_graph``, cached on the mesh): the shortest edge path,
    an upper bound on the true geodesic that follows the triangulation.

``anisotropic``
    Edge weights come from a Riemannian metric built from curvature directions, after Campen, Heistermann and
    Kobbelt, "Practical Anisotropic Geodesy" (SGP 2013): an edge ``e`` with unit direction ``t`` costs
    ``|e| * sqrt(t^T M_e t)``, and the metric makes moving *along* ridges and valleys cheap, so curves follow
    sharp features (the crest of a nose, a box edge, a spine) instead of cutting across them.

    Construction (:func:`feature_field`, then :func:`anisotropic_weights`):

    1. Normal-cycle curvature tensor (Cohen-Steiner & Morvan, SoCG 2003) per vertex ``v``:
       ``T_v = sum_e 0.5 * beta(e) * |e| * t_e t_e^T / area`` over the edges ``e`` incident to ``v``, where
       ``beta(e)`` is the signed dihedral angle (positive convex, negative concave; 0 on boundary and
       non-manifold edges) and ``area`` the barycentric vertex area over the same neighbourhood.
       ``smoothing`` passes of 1-ring summation (of the integrated tensors and of the areas) widen the
       neighbourhood (the normal-cycle estimate over a ball ``B``), which is what makes it usable on scans.
       Only the tangent block of ``T_v`` is used (tangent frame from the area-weighted vertex normal; its
       2x2 eigen-decomposition is done in closed form).
    2. The normal cycle *swaps* the principal directions: an edge with a large dihedral angle contributes a
       large eigenvalue *along the edge*, the direction of *least* bending. So the eigenvector ``d_v`` of the
       largest ``|eigenvalue|`` is the feature (ridge/valley) direction, and the anisotropy
       ``a_v = | |lambda_1| - |lambda_2| |`` says how much more the surface bends across ``d_v`` than along
       it. Using the *difference* means umbilic regions (sphere-like bumps, tips) get no preferred direction
       and are not made cheaper as a whole: only direction matters, not the size of the curvature. Ridges
       (convex) and valleys (concave) are treated alike. Checked numerically: on a cylinder ``d`` is the
       axis and ``a = 1/r``; on a sharp roof ``d`` follows the crest (``tests/plugins/test_tracers.py``).
    3. Scale invariance: ``s_v = clip(a_v / scale, 0, 1)`` with ``scale`` the ``saturation_percentile``-th
       percentile of the mesh's non-zero ``a_v``. ``a`` has units 1/length, so ``s`` does not depend on the
       mesh's units or size.
    4. Vertex metric ``M_v = I - b * s_v * d_v d_v^T`` with ``b = 1 - 1/(1+gamma)^2``: a step along a
       saturated feature costs ``|e| / (1+gamma)``; a step across one, or anywhere on a featureless region,
       costs ``|e|``. The edge metric is the mean of its two vertex metrics (a mean of SPD matrices is SPD):
       ``w_e = |e| * sqrt(1 - b/2 * (s_i (t.d_i)^2 + s_j (t.d_j)^2))``, between ``|e|/(1+gamma)`` and ``|e|``.

    The feature field (per ``smoothing``) and the weighted graph (per parameters) are cached on the mesh
    itself (``mesh.derived``, a small LRU that goes with the mesh), so a session that keeps its meshes
    traces at once after the first curve, and tracing on many meshes does not pile them up in memory.

Ids are internal (see :mod:`curvefm.geometry.mesh`); callers translate file ids with ``mesh.internal_ids`` first.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from pydantic import BaseModel, ConfigDict, Field
from scipy.sparse.csgraph import dijkstra

from curvefm.errors import Conflict, InvalidInput
from curvefm.geometry import DisplayMesh, Mesh, display_graph, edge_weight_graph, shortest_path
from curvefm.registry import TracerPlugin

# ----------------------------------------------------------------------------------------------------------
# Shared helpers


def _check_endpoints(mesh: Mesh, start: object, end: object) -> tuple[int, int]:
    out = []
    for what, v in (("start", start), ("end", end)):
        if isinstance(v, bool) or not isinstance(v, int | np.integer):
            raise InvalidInput(f"{what} vertex must be an integer vertex id, got {v!r}")
        if not 0 <= int(v) < mesh.n_vertices:
            raise InvalidInput(
                f"{what} vertex {int(v)} is out of range: mesh '{mesh.name}' has {mesh.n_vertices} vertices "
                f"(internal ids 0..{mesh.n_vertices - 1})"
            )
        out.append(int(v))
    return out[0], out[1]


#: first reach of each of the two searches, in multiples of the endpoints' straight-line distance (see ``_trace``)
FIRST_REACH = 0.75
#: factor by which the reach grows when the two searches did not meet at all
REACH_GROWTH = 2.0
#: bounded tries before one whole-mesh search
BOUNDED_TRIES = 3


def _trace(mesh: Mesh, graph: sp.csr_matrix, start: int, end: int) -> np.ndarray:
    """Shortest path from ``start`` to ``end`` (both included) on a symmetric weighted edge graph.

    Bidirectional Dijkstra in one scipy call: the searches from both ends, each cut off at a reach ``r``,
    settle exactly the vertices within ``r`` of their end. If the best meeting vertex ``v`` (least
    ``d_start(v) + d_end(v) = mu``) has ``mu <= 2 r - w_max`` (``w_max`` the longest edge), ``mu`` is the
    shortest distance: along a shortest path of length ``D <= mu`` the distance from ``start`` grows in steps
    of at most ``w_max``, so one of its vertices lies within ``r`` of both ends. Otherwise the next reach is
    ``(mu + w_max) / 2``, which the same argument shows is enough, or, where the searches did not meet, twice
    the last; after ``BOUNDED_TRIES`` one search covers the mesh. Two balls of about half the path's length hold
    far fewer vertices than one ball reaching past ``end`` (the tracing figures: docs/performance.md). Endpoints on
    different components are reported by :func:`curvefm.geometry.graph_paths.shortest_path` (the shared message).
    """
    if start == end:
        return np.array([start], dtype=np.int64)
    # the tracers' edge costs never exceed the edge lengths, so the mesh's longest edge bounds w_max (cached: a
    # maximum over every edge per trace cost 1.3 ms at 440k vertices)
    longest = mesh.derived.get(("longest edge",), lambda: float(mesh.edge_lengths.max()))
    reach = FIRST_REACH * float(np.linalg.norm(mesh.vertices[start] - mesh.vertices[end])) + longest
    for _ in range(BOUNDED_TRIES):
        mu, path = _meeting(graph, start, end, reach)
        if mu <= 2.0 * reach - longest:
            return path
        # where they met, mu bounds the shortest distance, so the next reach is enough
        reach = 0.5 * (mu + longest) if np.isfinite(mu) else REACH_GROWTH * reach
    dist, pred = dijkstra(graph, directed=True, indices=start, return_predecessors=True)  # type: ignore[call-overload]  # scipy-stubs: indices as an array only; scipy takes one int (1-D result)
    if not np.isfinite(dist[end]):
        return shortest_path(graph, start, end)  # raises the shared "different components" error
    return _walk(pred, start, end)[::-1]


def _meeting(graph: sp.csr_matrix, start: int, end: int, reach: float) -> tuple[float, np.ndarray]:
    """The searches from both ends cut off at ``reach``: the least ``d_start(v) + d_end(v)`` over the vertices
    both settled and the path through that vertex (``inf`` and no path where they did not meet)."""
    # our graphs are symmetric, so directed=True is the same search without scipy symmetrising per call
    dist, pred = dijkstra(graph, directed=True, indices=[start, end], return_predecessors=True, limit=reach)
    total = dist[0] + dist[1]
    meet = int(np.argmin(total))
    if not np.isfinite(total[meet]):
        return np.inf, np.empty(0, dtype=np.int64)
    return float(total[meet]), np.r_[_walk(pred[0], start, meet)[::-1], _walk(pred[1], end, meet)[1:]]


def _walk(pred: np.ndarray, root: int, vertex: int) -> np.ndarray:
    """The vertices from ``vertex`` back to ``root`` in a Dijkstra predecessor tree, both included."""
    path = [vertex]
    while path[-1] != root:
        path.append(int(pred[path[-1]]))
    return np.array(path, dtype=np.int64)


# ----------------------------------------------------------------------------------------------------------
# geodesic


class GeodesicParams(BaseModel):
    """The geodesic tracer has no parameters."""

    model_config = ConfigDict(extra="forbid")


def trace_geodesic(mesh: Mesh, start: int, end: int, params: GeodesicParams) -> np.ndarray:
    """Shortest edge path from ``start`` to ``end`` (internal ids, both included), Euclidean edge lengths."""
    start, end = _check_endpoints(mesh, start, end)
    return _trace(mesh, mesh.edge_graph, start, end)


#: half-width of the corridor around the display copy's path, in rings of display vertices (docs/performance.md)
CORRIDOR_RINGS = 2


def trace_geodesic_guided(mesh: Mesh, start: int, end: int, params: GeodesicParams, guide: DisplayMesh) -> np.ndarray:
    """:func:`trace_geodesic` on a big mesh, searched in a corridor: a short path between the display vertices
    nearest to ``start`` and ``end`` on the display copy ``guide`` (thousands of vertices, not millions), widened
    by ``CORRIDOR_RINGS`` rings of display vertices, then the mesh's shortest edge path from ``start`` to ``end``
    among the vertices nearest to that band (Dijkstra on that part of the mesh's edge graph). The answer is a
    path of the mesh's own edges between the given ends, as :func:`trace_geodesic`'s, and as short where the
    shortest path lies in the corridor; where the corridor does not join the ends the whole mesh is searched."""
    start, end = _check_endpoints(mesh, start, end)
    ids = corridor(mesh, guide, start, end)
    if ids is not None:
        first, last = np.searchsorted(ids, [start, end]).tolist()
        # one search over the corridor: a tube that two balls around its ends would mostly cover anyway
        dist, pred = dijkstra(mesh.edge_graph[ids][:, ids], directed=True, indices=first, return_predecessors=True)
        if np.isfinite(dist[last]):
            return ids[_walk(pred, first, last)[::-1]]
    return _trace(mesh, mesh.edge_graph, start, end)  # the corridor (or the display copy) does not join the ends


def corridor(mesh: Mesh, guide: DisplayMesh, start: int, end: int) -> np.ndarray | None:
    """The vertices of ``mesh`` (ascending) nearest to the display vertices within ``CORRIDOR_RINGS`` rings of a
    short path on the display copy ``guide`` between the display vertices nearest to ``start`` and ``end``
    (``None`` where the display copy does not join them)."""
    coarse = display_graph(mesh, guide)
    try:
        rows = _guide_path(coarse, mesh.vertices[guide.vertex_ids], *guide.nearest[[start, end]].tolist())
    except Conflict:
        return None
    band = dijkstra(coarse, directed=True, indices=rows, min_only=True, unweighted=True, limit=CORRIDOR_RINGS)
    return guide.cover(np.flatnonzero(np.isfinite(band)))


def _guide_path(graph: sp.csr_matrix, vertices: np.ndarray, start: int, end: int) -> np.ndarray:
    """A short path on a display copy: the searches from both ends grown until they meet, the best meeting vertex
    taken without :func:`_trace`'s proof that no shorter path exists (a corridor needs no more, and the proof's
    bound, from the copy's longest edge, a dozen times its mean, cost a second search)."""
    if start == end:
        return np.array([start], dtype=np.int64)
    reach = FIRST_REACH * float(np.linalg.norm(vertices[start] - vertices[end])) + float(graph.data.mean())
    for _ in range(BOUNDED_TRIES):
        mu, path = _meeting(graph, start, end, reach)
        if np.isfinite(mu):
            return path
        reach *= REACH_GROWTH
    return shortest_path(graph, start, end)


GEODESIC = TracerPlugin(
    name="geodesic",
    description="Shortest path along mesh edges (Dijkstra, Euclidean edge lengths)",
    Params=GeodesicParams,
    run=trace_geodesic,
    run_guided=trace_geodesic_guided,
)


# ----------------------------------------------------------------------------------------------------------
# anisotropic


class AnisotropicParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    strength: float = Field(
        4.0,
        ge=0.0,
        le=100.0,
        description="gamma: a step along a fully saturated ridge or valley costs |e|/(1+gamma), a step "
        "across it costs |e|. 0 gives the plain geodesic; larger values follow features more eagerly (and "
        "take longer detours to reach them)",
    )
    smoothing: int = Field(
        2,
        ge=0,
        le=10,
        description="passes of 1-ring summation of the normal-cycle curvature tensor before its principal "
        "direction is taken (0: one ring). More passes ignore small-scale noise and detail",
    )
    saturation_percentile: float = Field(
        90.0,
        gt=0.0,
        le=100.0,
        description="curvature anisotropy at this percentile of the mesh's non-zero values, and above, "
        "counts as a fully saturated feature; lower values treat more of the surface as feature. Makes the "
        "weighting independent of the mesh's scale and units",
    )


def _signed_dihedral(mesh: Mesh) -> np.ndarray:
    """Signed dihedral angle per edge of ``mesh.edges``: > 0 convex, < 0 concave, 0 on boundary/non-manifold.

    Face orientation needs only to be consistent across each edge; where two faces disagree the second normal
    is flipped. A globally flipped orientation negates every angle, which the tracer does not care about.
    """
    v, f, n = mesh.vertices, mesh.faces, mesh.n_vertices
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    # half-edges a->b of face k, opposite corner c
    a = f.reshape(-1)
    b = f[:, [1, 2, 0]].reshape(-1)
    c = f[:, [2, 0, 1]].reshape(-1)
    face = np.repeat(np.arange(len(f)), 3)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * n + hi
    order = np.argsort(key, kind="stable")
    key_s = key[order]
    edge_key = mesh.edges[:, 0] * n + mesh.edges[:, 1]
    first = np.searchsorted(key_s, edge_key, side="left")
    count = np.searchsorted(key_s, edge_key, side="right") - first
    beta = np.zeros(len(edge_key))
    ok = count == 2
    h1, h2 = order[first[ok]], order[first[ok] + 1]
    n1, n2 = fn[face[h1]], fn[face[h2]]
    same_dir = a[h1] == a[h2]  # both faces traverse the edge the same way: inconsistent orientation
    n2 = np.where(same_dir[:, None], -n2, n2)
    cos = np.clip(np.einsum("ij,ij->i", n1, n2), -1.0, 1.0)
    sin = np.linalg.norm(np.cross(n1, n2), axis=1)
    angle = np.arctan2(sin, cos)
    # convex when the other face's far corner lies below the first face's plane
    height = np.einsum("ij,ij->i", v[c[h2]] - v[a[h1]], n1)
    beta[ok] = np.where(height > 0, -angle, angle)
    return beta


def feature_field(mesh: Mesh, smoothing: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Per-vertex feature direction and curvature anisotropy from the normal-cycle tensor.

    Returns
    -------
    directions : (n, 3) unit vectors, the eigenvector of the largest ``|eigenvalue|`` of the tangent-projected
        normal-cycle tensor: the direction *along* a ridge or valley (least bending).
    anisotropy : (n,) ``|lambda_1| - |lambda_2| >= 0`` in units of 1/length (0 where bending is the same in
        every direction, e.g. planes and umbilics).
    """
    v, f, n = mesh.vertices, mesh.faces, mesh.n_vertices
    e = mesh.edges
    vec = v[e[:, 1]] - v[e[:, 0]]
    length = mesh.edge_lengths
    t = vec / np.where(length > 0, length, 1.0)[:, None]
    w = 0.5 * _signed_dihedral(mesh) * length
    # 6 unique components of sum w t t^T, scattered to both endpoints
    comps = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
    ends = np.r_[e[:, 0], e[:, 1]]
    raw = np.empty((n, 6))
    for k, (i, j) in enumerate(comps):
        val = w * t[:, i] * t[:, j]
        raw[:, k] = np.bincount(ends, np.r_[val, val], minlength=n)
    fa = mesh.face_areas
    area = np.bincount(f.reshape(-1), np.repeat(fa / 3.0, 3), minlength=n)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])  # area-weighted (x2) face normals
    normal = np.stack([np.bincount(f.reshape(-1), np.repeat(fn[:, k], 3), minlength=n) for k in range(3)], 1)
    if smoothing:
        ring = mesh.edge_graph.copy()
        ring.data[:] = 1.0
        ring = (ring + sp.identity(n, format="csr")).tocsr()
        stacked = np.column_stack([raw, area, normal])
        for _ in range(smoothing):
            stacked = ring @ stacked
        raw, area, normal = stacked[:, :6], stacked[:, 6], stacked[:, 7:]
    raw /= np.maximum(area, np.finfo(float).tiny)[:, None]
    # tangent frame (u, w) from the normal, then the 2x2 tangent block of T in closed form (no 3x3 eigh)
    nn = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.divide(normal, nn, out=np.tile([0.0, 0.0, 1.0], (n, 1)), where=nn > 0)
    helper = np.eye(3)[np.argmin(np.abs(normal), axis=1)]
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w_ = np.cross(normal, u)

    def quad(p: np.ndarray, q: np.ndarray) -> np.ndarray:  # p^T T q from the 6 stored components
        return (
            raw[:, 0] * p[:, 0] * q[:, 0]
            + raw[:, 1] * p[:, 1] * q[:, 1]
            + raw[:, 2] * p[:, 2] * q[:, 2]
            + raw[:, 3] * (p[:, 0] * q[:, 1] + p[:, 1] * q[:, 0])
            + raw[:, 4] * (p[:, 0] * q[:, 2] + p[:, 2] * q[:, 0])
            + raw[:, 5] * (p[:, 1] * q[:, 2] + p[:, 2] * q[:, 1])
        )

    a, b, c = quad(u, u), quad(u, w_), quad(w_, w_)
    mean, radius = 0.5 * (a + c), np.hypot(0.5 * (a - c), b)
    lam_hi, lam_lo = mean + radius, mean - radius  # algebraic order
    theta = 0.5 * np.arctan2(2.0 * b, a - c)  # angle of the eigenvector of lam_hi from u
    theta = np.where(np.abs(lam_hi) >= np.abs(lam_lo), theta, theta + 0.5 * np.pi)
    directions = np.cos(theta)[:, None] * u + np.sin(theta)[:, None] * w_
    anisotropy = np.abs(np.abs(lam_hi) - np.abs(lam_lo))
    return directions, anisotropy


def anisotropic_weights(mesh: Mesh, params: AnisotropicParams) -> np.ndarray:
    """Edge costs (aligned with ``mesh.edges``) of the anisotropic metric; see the module docstring."""
    key = ("anisotropic feature field", params.smoothing)
    directions, anisotropy = mesh.derived.get(key, lambda: feature_field(mesh, params.smoothing))
    positive = anisotropy[anisotropy > 1e-12 * max(float(anisotropy.max()), 0.0)]
    length = mesh.edge_lengths
    if positive.size == 0 or params.strength == 0:
        return length.copy()
    scale = float(np.percentile(positive, params.saturation_percentile))
    s = np.clip(anisotropy / scale, 0.0, 1.0)
    b = 1.0 - 1.0 / (1.0 + params.strength) ** 2
    e = mesh.edges
    t = (mesh.vertices[e[:, 1]] - mesh.vertices[e[:, 0]]) / np.where(length > 0, length, 1.0)[:, None]
    ci = np.einsum("ij,ij->i", t, directions[e[:, 0]])
    cj = np.einsum("ij,ij->i", t, directions[e[:, 1]])
    quad = 1.0 - 0.5 * b * (s[e[:, 0]] * ci**2 + s[e[:, 1]] * cj**2)
    return length * np.sqrt(np.maximum(quad, 1.0 / (1.0 + params.strength) ** 2))


def anisotropic_graph(mesh: Mesh, params: AnisotropicParams) -> sp.csr_matrix:
    """The anisotropic edge graph, cached on the mesh per parameters."""
    key = ("anisotropic graph", params.strength, params.smoothing, params.saturation_percentile)
    return mesh.derived.get(
        key, lambda: edge_weight_graph(mesh.n_vertices, mesh.edges, anisotropic_weights(mesh, params))
    )


def trace_anisotropic(mesh: Mesh, start: int, end: int, params: AnisotropicParams) -> np.ndarray:
    """Shortest path under the curvature-aligned metric (internal ids, start and end included)."""
    start, end = _check_endpoints(mesh, start, end)
    return _trace(mesh, anisotropic_graph(mesh, params), start, end)


ANISOTROPIC = TracerPlugin(
    name="anisotropic",
    description="Shortest path under a curvature-aligned Riemannian metric (Campen et al. 2013): follows "
    "ridges and valleys, cheap along sharp features and normal cost across them",
    Params=AnisotropicParams,
    run=trace_anisotropic,
)
