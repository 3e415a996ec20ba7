"""A suggested next curve: where the live maps are least certain, and where they send it.

The person drawing curves wants to know where one more curve helps most. Both ends are chosen on the source,
from the round-trip drift of the maps (:mod:`curvefm.fmap.round_trip`: large where no curve constrains them) and
from the geodesic distance to what is already given, like a farthest-point sampling weighted by the drift:

* the start maximises ``sqrt(drift(v)) * d(v)`` with ``d`` the distance to the nearest vertex of any curve (1
  everywhere when there is none);
* the end maximises ``sqrt(drift(v)) * min(d(v), d_start(v))``, so it lies far from the curves and from the start
  too, and the path joining them crosses unconstrained surface (where that product is 0 everywhere, no drift or
  curves everywhere, the end is the point farthest from the start).

Neither shape ever gets a curve of no length: the ends differ on the source, and where the maps send both to one
target vertex the second image is moved away (:func:`_apart`).

The square root was chosen by measurement on FAUST 000 -> 011 and cat -> lion against the drift alone and the
distance alone (benchmarks/bench_suggestions.py; the figures and how far they fall short of issue 35's target are in
docs/accuracy.md#suggested-curves).

The first suggestion, made from no curve, must not join two points that a left-right mirror swaps (FAUST's two
feet): such a curve is mapped onto itself by the mirror, its side tells nothing, and one curve gave a flipped map.
Intrinsic signatures cannot tell mirror twins apart, which is what finds them: the first end also maximises
``unlike(v)``, the distance of v's wave kernel signature from the start's (over its largest), 0 at the start's
twin. It joins a foot to a hand on FAUST (one curve: 0.042 instead of 0.156). Later suggestions keep the rule
above: with the factor (or its square root) there too, cat -> lion lost (docs/accuracy.md#suggested-curves).

Their images on the target are the maps' own (nearest neighbours in both spectral embeddings, as the default
pointwise conversion): the person accepts them, or moves an end where the map is wrong. Distances are graph
shortest paths along the mesh edges, in units of ``sqrt(area)``: one multi-source Dijkstra from the curves and one
from the start, a pass over the mesh each, so the suggestion is read in a request of its own and no edit waits for
it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import dijkstra

from curvefm.geometry import Mesh
from curvefm.pointwise.conversion import pointwise_from_both
from curvefm.spectral import Basis, ShapePair
from curvefm.spectral.descriptors import wave_kernel_signature


@dataclass(frozen=True)
class SuggestedCurve:
    """Internal ids: the curve's ``source`` ends (start, end) and their ``target`` images through the maps."""

    source: tuple[int, int]
    target: tuple[int, int]


def suggest_curve(
    pair: ShapePair, C_MN: np.ndarray, C_NM: np.ndarray, drift_M: np.ndarray, curves_M: np.ndarray
) -> SuggestedCurve:
    """The next curve to draw, given both maps (``C_MN`` k_N x k_M, ``C_NM`` k_M x k_N, on ``pair``'s bases),
    the round-trip ``drift_M`` per source vertex and the internal ids ``curves_M`` of the curves' source vertices."""
    mesh_M, weight = pair.mesh_M, np.sqrt(np.maximum(drift_M, 0.0))
    from_curves = _distances(mesh_M, curves_M) if len(curves_M) else np.ones(mesh_M.n_vertices)
    start = int(np.argmax(weight * from_curves))
    from_start = _distances(mesh_M, np.array([start]))
    score = weight * np.minimum(from_curves, from_start) * (1.0 if len(curves_M) else _unlike(pair.basis_M, start))
    end = int(np.argmax(score if score.max() > 0 else from_start))  # never the start: a curve of no length
    rows = np.array([start, end])
    images = pointwise_from_both(C_NM, C_MN, pair.basis_N, pair.basis_M, rows=rows)
    return SuggestedCurve(source=(start, end), target=_apart(pair.mesh_N, int(images[0]), int(images[1])))


def _apart(mesh: Mesh, first: int, second: int) -> tuple[int, int]:
    """Two images as the ends of a curve: where the maps send both ends to one vertex (zero maps, as a new
    session's, send every vertex to one), a curve of no length would be proposed, so the second end goes to the
    vertex farthest from the first instead (an image as meaningless as the map's, which the person moves)."""
    if first != second:
        return first, second
    return first, int(np.argmax(_distances(mesh, np.array([first]))))


def _unlike(basis: Basis, vertex: int) -> np.ndarray:
    """How far each vertex's wave kernel signature lies from ``vertex``'s, over the largest such distance (0 at
    ``vertex`` and at its mirror twin, whose signature is the same). Each energy is divided by its mean over the
    shape, so every band counts alike."""
    signature = wave_kernel_signature(basis)
    signature = signature / (basis.mass @ signature)
    apart = np.linalg.norm(signature - signature[vertex], axis=1)
    return apart / apart.max()


def _distances(mesh: Mesh, sources: np.ndarray) -> np.ndarray:
    """Graph distance (along edges, units of ``sqrt(area)``) from every vertex to the nearest of ``sources``; a
    part of the mesh that no path reaches counts as twice the farthest distance reached (far, and finite)."""
    nearest = np.asarray(dijkstra(mesh.edge_graph, indices=np.unique(sources), min_only=True))
    reached = nearest[np.isfinite(nearest)]
    return np.nan_to_num(nearest, posinf=2 * reached.max()) / np.sqrt(mesh.area)
