"""Converter plugin ``rhm``: Reversible Harmonic Maps (Ezuz, Solomon, Ben-Chen, "Reversible Harmonic Maps
between Discrete Surfaces", ACM TOG 38(2), 2019; arXiv 2018).

Formulation followed: the paper's, with the weights and schedule of the authors' code as carried by the
public Python port (RobinMagnet/ReversibleHarmonicMaps, ``rhm_refine``). Both meshes are scaled to unit area
and embedded in R^dim by geodesic MDS (:mod:`curvefm.pointwise.geodesic_mds`): X_M (m x dim),
X_N (n x dim). The unknowns are the maps P_MN, P_NM (rows: a vertex or a point on a triangle of the other
mesh) and the continuous images X_MN ~ P_MN X_N, X_NM ~ P_NM X_M. The energy, summed over both directions, is::

    alpha * tr(X_MN^T L_M X_MN)                 Dirichlet energy of the map M -> N
    + (1 - alpha) * |X_N - P_NM X_MN|^2_{A_N}   reversibility: N -> M -> N is the identity
    + beta_t * |X_MN - P_MN X_N|^2_{A_M}        coupling of X_MN to the map

The Dirichlet and reversibility terms act on the continuous images, which the coupling term ties to the
maps. It is minimised alternately: each P row by a closest-point projection in the stacked embedding
[sqrt(1 - alpha) X_MN, sqrt(beta_t) X_M] (vertices or triangles of M, for a vertex of N), each X by one
sparse SPD solve ``(alpha L + (1 - alpha) P^T A P + beta_t A) X = rhs``. beta_t = min(t * beta, beta_max)
(the authors' schedule: 5e-3 rising to 0.5 over 100 iterations); alpha = 5e-4. It stops when the energy
changes by less than ``tol`` (relative) over five iterations.

The ends of the user's curves stay pinned (:class:`~curvefm.pointwise.CurvePins`): after every projection each
end maps to the same end of its partner curve (the exact vertex, also with triangle projection), and in every solve
an end's continuous image is coupled to its pin with ``pin_weight`` (10, per vertex area) on top of beta_t, so the
exact points shape the smooth images, and through them their neighbours' projections, from the first iteration
(with the coupling alone, 0.005 at first, more curves did not help RHM on cat -> lion; issue 35). The curves'
inner vertices are free: their arc-length partners were farther from the truth than the map's own images
(docs/decisions.md#curve-pins); RHM's ZoomOut start ignores them too by default.

Anchor (not in the paper): after every vertex projection, a vertex whose image lies farther than
``anchor_radius`` (0.15, in the image's geodesic embedding at unit area) from its image under the anchor maps goes
to that image instead (a pinned end excepted). The anchor maps are those the guard of
:func:`curvefm.matching.convert` would accept: ZoomOut's start where it makes no intrinsic figure worse than the
``nearest-neighbor`` converter's maps, else those. So RHM refines a map the guard trusts, but does not carry a
vertex across the shape. When every curve vertex was pinned by arc length (before issue 35), the
anchor released the pins that were far off (on cat -> lion with 10 curves at radius 0.1, 34 of the 272 pinned
source vertices). Anchored to the nearest-neighbour maps on every pair, RHM lost much of its
gain where ZoomOut's start was good and the nearest-neighbour one poor (cat0 -> cat2 with 2 curves: 0.0478
against 0.0259). Without the anchor RHM ended worse than its start on two rows of the reproduce suite (cat -> lion
with 10 curves, wolf -> dog with 2); see experiments/refinement_guard.py and
docs/decisions.md#the-refinement-guard.

Big meshes: every iteration factorises a sparse system of the mesh's size, so above ``dense_up_to`` vertices
RHM runs on decimated copies of both shapes (``coarse_vertices``, quadric decimation); the copies' embeddings
and continuous images, interpolated to every vertex, then give one projection step at full resolution
(:func:`coarse_reversible_harmonic_maps`).

Deviations (errors: mean geodesic error / sqrt(area), 10 curves, from benchmarks/bench_converters.py):

* Start: by default from ``zoomout``'s maps rather than the nearest-neighbour ones. RHM keeps the start's
  large-scale structure; from ZoomOut it ends far lower (FAUST 0.009 instead of 0.020, cat -> lion 0.023
  instead of 0.027).
* Projection: onto vertices by default. Projecting onto triangles every iteration (the paper's exact
  vertex-to-point maps) reached a lower energy but worse maps, 7x slower (FAUST 0.020 against 0.009, cat ->
  lion 0.035 against 0.023), as the issue's runs of the public port did (FAUST 0.032 precise, 0.024 fast).
* MDS samples are geodesic farthest points (the port decimates with meshlab); MDS is classical scaling
  refined by at most 100 SMACOF iterations.
* Stopping: relative energy change over five iterations (the port: an absolute 1e-9 over five).
* The linear system changes every iteration (P^T A P follows the map), so it is factorised every time
  (SuperLU, about 50 ms at 7k vertices); Jacobi-preconditioned CG needed 40-70 iterations and was slower.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, Literal, cast

import numpy as np
import scipy.sparse as sp
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.sparse.linalg import splu
from scipy.spatial import cKDTree

from curvefm.fmap import FunctionalMaps
from curvefm.geometry import Mesh, build_mesh, closest_point_weights, cotangent_laplacian, decimate
from curvefm.plugins.converters import NearestNeighborParams, convert_nearest_neighbor
from curvefm.plugins.refiner import Curves, IterativeRefiner, Start
from curvefm.plugins.zoomout import ZoomOutParams, convert_zoomout, zoomout_basis_size
from curvefm.pointwise import (
    CurvePins,
    PointwiseMaps,
    closest_points,
    compare,
    geodesic_embedding,
    initial_maps,
    measure,
    no_pins,
    unit_area,
)
from curvefm.progress import Progress, no_progress, scaled
from curvefm.spectral import ShapePair

ENERGY_WINDOW = 5  # iterations over which the energy change is measured
COARSE_VERTICES = 5_000  # vertices of the decimated copies RHM iterates on above dense_up_to
#: RHM on 5,000-vertex copies was as good as on every vertex on FAUST (0.0094 against 0.0092) and takes 19 s at
#: 27.5k vertices, where every vertex would take minutes: a lower threshold than ZoomOut's and ICP's
# chosen in docs/decisions.md#refining-big-shapes-on-samples
RHM_DENSE_UP_TO = 20_000
#: how far (units of sqrt(area), in the geodesic embedding) RHM may carry a vertex's image from the anchor maps; on
#: cat -> lion (10 curves, nearest-neighbour anchor) 0.1 / 0.15 / 0.2 gave 0.0215 / 0.0235 / 0.0266 against a start of
#: 0.0263, and with 2 curves 0.0301 / 0.0238 / 0.0234 against 0.0382 (docs/decisions.md#the-refinement-guard)
# chosen in docs/decisions.md#the-refinement-guard
ANCHOR_RADIUS = 0.15
#: the pinned ends' continuous images are coupled to their pins with this weight (per vertex area) from the first
#: iteration, against the coupling's 0.005 rising to 0.5: from 10 curves on cat -> lion (endpoints on the lion) RHM
#: ended at 0.0225 / 0.0186 instead of 0.0231 / 0.0189, no worse than from 2; 1000 made 10 curves worse than 2 there
# chosen in docs/decisions.md#curve-pins
PIN_WEIGHT = 10.0


class RhmParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    init: Literal["zoomout", "nearest-neighbor"] = Field(
        "zoomout", description="maps to start from: the zoomout converter's, or the nearest-neighbor ones"
    )
    init_zoomout: ZoomOutParams = Field(
        default_factory=lambda: ZoomOutParams(curve_interior_weight=0.0),
        description="parameters of the zoomout start (with init='zoomout'); by default its fits ignore the curves' "
        "inner vertices (docs/decisions.md#curve-pins)",
    )
    alpha: float = Field(5e-4, gt=0, lt=1, description="weight of the Dirichlet energy; reversibility has 1 - alpha")
    beta: float = Field(5e-3, gt=0, description="coupling weight at iteration 1; it grows by beta per iteration")
    beta_max: float = Field(0.5, gt=0, description="the coupling weight stops growing here")
    embedding_dim: int = Field(8, ge=2, le=64, description="dimension of the geodesic MDS embedding of each shape")
    samples: int = Field(500, ge=10, le=5000, description="farthest-point samples whose geodesic distances MDS fits")
    max_iterations: int = Field(200, ge=1, le=10000, description="most iterations")
    min_iterations: int = Field(20, ge=ENERGY_WINDOW + 1, le=10000, description="iterations before the stopping test")
    tol: float = Field(
        1e-6, ge=0, description="stop when the energy changes by less than this fraction over five iterations"
    )
    projection: Literal["vertex", "triangle"] = Field(
        "vertex", description="map each vertex to the closest vertex (fast) or closest point on a triangle"
    )
    dense_up_to: int = Field(
        RHM_DENSE_UP_TO,
        ge=0,
        le=10**9,
        description="shapes with more vertices than this are refined on decimated copies of coarse_vertices "
        "vertices, and every vertex is projected once at the end",
    )
    coarse_vertices: int = Field(
        COARSE_VERTICES, ge=200, le=10**6, description="vertices of the decimated copies (above dense_up_to)"
    )
    anchor_radius: float = Field(
        ANCHOR_RADIUS,
        ge=0,
        description="after every projection, a vertex whose image lies farther than this (units of sqrt(area), "
        "geodesic embedding) from its image under the anchor maps (ZoomOut's start where the guard accepts it, "
        "else the nearest-neighbour maps) goes to that image (0: off)",
    )
    pin_weight: float = Field(
        PIN_WEIGHT,
        ge=0,
        description="extra coupling weight (per vertex area) of the pinned curve ends' continuous images to their "
        "pins, from the first iteration: the ends act on their neighbours through the smooth images (0: off)",
    )

    @model_validator(mode="after")
    def _consistent(self) -> RhmParams:
        if self.beta_max < self.beta:
            raise ValueError(f"beta_max ({self.beta_max}) must be at least beta ({self.beta})")
        if self.samples <= self.embedding_dim:
            raise ValueError(f"samples ({self.samples}) must exceed embedding_dim ({self.embedding_dim})")
        return self


@dataclass
class _Shape:
    """One mesh at unit area: faces, cotangent Laplacian, vertex areas and geodesic embedding."""

    faces: np.ndarray
    L: sp.csr_matrix
    mass: np.ndarray
    X: np.ndarray


@dataclass
class _Map:
    """One direction, domain -> image: the map as sparse rows P (n_domain x n_image) with its vertex version
    ``p2p``, and ``X``, the continuous image of each domain vertex in the image's embedding."""

    domain: _Shape
    image: _Shape
    P: sp.csr_matrix
    p2p: np.ndarray
    X: np.ndarray
    pinned: np.ndarray  # (n_domain,) the image vertex each domain vertex must map to, FREE (-1) if none
    anchor: np.ndarray | None = None  # (n_domain,) each domain vertex's image vertex under the anchor maps


def prepare_shape(mesh: Mesh, params: RhmParams) -> _Shape:
    unit = unit_area(mesh)
    L, mass = cotangent_laplacian(unit.vertices, unit.faces)
    X = geodesic_embedding(unit, L, mass, params.embedding_dim, params.samples)
    return _Shape(unit.faces, L, mass, X)


def vertex_rows(p2p: np.ndarray, n_image: int) -> sp.csr_matrix:
    n = len(p2p)
    return sp.csr_matrix((np.ones(n), (np.arange(n), p2p)), shape=(n, n_image))


def projection_embeddings(
    back_X: np.ndarray, image_X: np.ndarray, domain_X: np.ndarray, fwd_X: np.ndarray, alpha: float, beta: float
) -> tuple[np.ndarray, np.ndarray]:
    """Data (image vertices) and queries (domain vertices) of the projection step, in the stacked embedding
    ``[sqrt(1 - alpha) X_reversed, sqrt(beta) X_coupled]``."""
    data = np.hstack([np.sqrt(1 - alpha) * back_X, np.sqrt(beta) * image_X])
    queries = np.hstack([np.sqrt(1 - alpha) * domain_X, np.sqrt(beta) * fwd_X])
    return data, queries


def near_anchor(p2p: np.ndarray, anchor: np.ndarray | None, image_X: np.ndarray, radius: float) -> np.ndarray:
    """``p2p`` with each entry that lands farther than ``radius`` from ``anchor``'s (both: an image vertex per
    domain vertex; distances in the image embedding ``image_X``) replaced by the anchor's: RHM refines the
    start's correspondence locally but does not carry a vertex across the shape."""
    if anchor is None or radius <= 0:
        return p2p
    return np.where(np.linalg.norm(image_X[p2p] - image_X[anchor], axis=1) > radius, anchor, p2p)


def project(fwd: _Map, back: _Map, alpha: float, beta: float, projection: str, radius: float = 0.0) -> None:
    """Update ``fwd.P`` and ``fwd.p2p``: each domain vertex y goes to the point x of the image minimising
    ``(1 - alpha) |back.X(x) - X_domain(y)|^2 + beta |X_image(x) - fwd.X(y)|^2`` (reversibility, coupling);
    with vertex projection any vertex whose image lies farther than ``radius`` from its image under ``fwd.anchor``
    goes to that image instead; pinned vertices (the curves' ends) go to their pin."""
    data, queries = projection_embeddings(back.X, fwd.image.X, fwd.domain.X, fwd.X, alpha, beta)
    if projection == "vertex":
        nearest = cast(np.ndarray, cKDTree(data).query(queries, workers=-1)[1])  # many queries: an array
        anchored = near_anchor(nearest, fwd.anchor, fwd.image.X, radius)
        fwd.p2p = np.where(fwd.pinned >= 0, fwd.pinned, anchored)
        fwd.P = vertex_rows(fwd.p2p, len(data))
        return
    fixed = fwd.pinned >= 0
    corners, weights = closest_points(data, fwd.image.faces, queries)
    corners[fixed] = fwd.pinned[fixed, None]
    weights[fixed] = (1.0, 0.0, 0.0)
    rows = np.repeat(np.arange(len(queries)), 3)
    fwd.P = sp.csr_matrix((weights.ravel(), (rows, corners.ravel())), shape=(len(queries), len(data)))
    fwd.p2p = corners[np.arange(len(corners)), np.argmax(weights, axis=1)]


def solve_image(fwd: _Map, back: _Map, alpha: float, beta: float, pin_weight: float = 0.0) -> None:
    """Update ``fwd.X``: the minimiser of its Dirichlet, reversibility and coupling terms (the coupling of pinned
    vertices raised by ``pin_weight``)."""
    dom, img = fwd.domain, fwd.image
    coupling = beta * dom.mass + pin_weight * dom.mass * (fwd.pinned >= 0)
    K = alpha * dom.L + (1 - alpha) * (back.P.T @ sp.diags(img.mass) @ back.P) + sp.diags(coupling)
    rhs = (1 - alpha) * (back.P.T @ (img.mass[:, None] * img.X)) + coupling[:, None] * (fwd.P @ img.X)
    # K is symmetric positive definite: a symmetric ordering and no pivoting factorise it 15% faster
    lu = splu(K.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    fwd.X = lu.solve(rhs)


def energy(fwd: _Map, back: _Map, alpha: float, beta: float) -> float:
    """The terms of the energy that belong to ``fwd`` (its Dirichlet, reversibility and coupling terms)."""
    dom, img = fwd.domain, fwd.image
    dirichlet = np.sum(fwd.X * (dom.L @ fwd.X))
    reversibility = np.sum(img.mass[:, None] * (img.X - back.P @ fwd.X) ** 2)
    coupling = np.sum(dom.mass[:, None] * (fwd.X - fwd.P @ img.X) ** 2)
    return alpha * dirichlet + (1 - alpha) * reversibility + beta * coupling


def settled(energies: list[float], tol: float) -> bool:
    """Whether the energy changed by at most ``tol`` (relative) over the last ENERGY_WINDOW iterations."""
    return abs(energies[-1] - energies[-1 - ENERGY_WINDOW]) <= tol * abs(energies[-1])


@dataclass
class _Iterate:
    """RHM's state: both maps (``MN.p2p`` is ``p2p_MN``), the energy after each iteration and the last coupling
    weight."""

    MN: _Map
    NM: _Map
    energies: list[float] = field(default_factory=list)
    beta: float = 0.0


@dataclass(frozen=True)
class RhmStart(Start):
    """RHM's start: also the ``anchor`` maps (None: no anchor)."""

    anchor: PointwiseMaps | None = None


class Rhm(IterativeRefiner[RhmParams, _Iterate]):
    """RHM as an :class:`~curvefm.plugins.refiner.IterativeRefiner`: it starts from ZoomOut's maps (or the
    ``nearest-neighbor`` ones) with the curves pinned and anchored; each step projects both maps and solves for
    both continuous images; it stops when the energy settles."""

    name = "rhm"
    description = "Reversible Harmonic Maps (Ezuz, Solomon, Ben-Chen 2018), both directions at once"
    Params = RhmParams

    def basis_size(self, params: RhmParams) -> int:
        """The zoomout start's basis size (none for the nearest-neighbour start)."""
        return zoomout_basis_size(params.init_zoomout) if params.init == "zoomout" else 0

    def start(
        self,
        pair: ShapePair,
        fmaps: FunctionalMaps,
        params: RhmParams,
        progress: Progress = no_progress,
        curves: Curves = (),
    ) -> RhmStart:
        """ZoomOut's maps or the ``nearest-neighbor`` ones, the curves' pins, and the anchor maps: those the guard
        of :func:`curvefm.matching.convert` would accept (ZoomOut's where they make no figure worse, else the
        ``nearest-neighbor`` converter's)."""
        progress(0.0, "initial maps (nearest neighbours)")
        anchor = convert_nearest_neighbor(pair, fmaps, NearestNeighborParams()) if params.anchor_radius > 0 else None
        if params.init == "zoomout":
            maps = convert_zoomout(pair, fmaps, params.init_zoomout, progress, curves)
            if anchor is not None and not compare(measure(pair, maps, curves), measure(pair, anchor, curves)):
                anchor = maps  # the guard (curvefm.matching.convert) would return ZoomOut's maps: anchor to those
        else:
            maps = initial_maps(pair, fmaps)
        return RhmStart(maps, CurvePins.from_curves(pair.mesh_M, pair.mesh_N, curves), anchor=anchor)

    def begin(
        self, maps: PointwiseMaps, shape_M: _Shape, shape_N: _Shape, pins: CurvePins, anchor: PointwiseMaps | None
    ) -> _Iterate:
        """Both maps from ``maps`` with the curves pinned, as vertex rows, and their continuous images."""
        p2p_MN, p2p_NM = pins.pin_MN(maps.p2p_MN), pins.pin_NM(maps.p2p_NM)
        P_MN, P_NM = vertex_rows(p2p_MN, len(shape_N.X)), vertex_rows(p2p_NM, len(shape_M.X))
        anchor_MN, anchor_NM = (None, None) if anchor is None else (anchor.p2p_MN, anchor.p2p_NM)
        MN = _Map(shape_M, shape_N, P_MN, p2p_MN, P_MN @ shape_N.X, pins.M_to_N, anchor_MN)
        NM = _Map(shape_N, shape_M, P_NM, p2p_NM, P_NM @ shape_M.X, pins.N_to_M, anchor_NM)
        return _Iterate(MN, NM)

    def schedule(self, state: _Iterate, params: RhmParams) -> range:
        return range(1, params.max_iterations + 1)

    def step(self, state: _Iterate, t: int, params: RhmParams) -> bool:
        state.beta = beta = min(t * params.beta, params.beta_max)
        MN, NM = state.MN, state.NM
        for fwd, back in ((NM, MN), (MN, NM)):
            project(fwd, back, params.alpha, beta, params.projection, params.anchor_radius)
            solve_image(fwd, back, params.alpha, beta, params.pin_weight)
        state.energies.append(energy(MN, NM, params.alpha, beta) + energy(NM, MN, params.alpha, beta))
        return t >= params.min_iterations and settled(state.energies, params.tol)

    def step_message(self, t: int, params: RhmParams) -> str:
        return f"RHM iteration {t} of at most {params.max_iterations}"

    def end_message(self, state: _Iterate, steps_run: int, params: RhmParams) -> str:
        return f"stopped after {steps_run} iterations, energy {state.energies[-1]:.6g}"

    def stages(
        self,
        pair: ShapePair,
        fmaps: FunctionalMaps,
        params: RhmParams,
        progress: Progress = no_progress,
        curves: Curves = (),
    ) -> Iterator[tuple[str, PointwiseMaps]]:
        """RHM's maps, then, only when the guard asks (RHM's raised an intrinsic figure), its ZoomOut start: on
        cat -> lion with 2 curves RHM gained (0.045 -> 0.028) but raised the inverse deviation, and without this
        stage the guard fell back to the nearest-neighbour maps rather than ZoomOut's (0.030)."""
        start = self.start(pair, fmaps, params, scaled(progress, 0.0, 0.3), curves)
        yield "", self.refine_from(pair, start, params, progress, curves)
        if params.init == "zoomout":
            yield "its ZoomOut start", start.maps

    def convert(self, *args: Any, **kwargs: Any) -> PointwiseMaps:
        """RHM's maps (the first of :meth:`stages`, which takes the same arguments)."""
        return next(self.stages(*args, **kwargs))[1]

    def refine_from(
        self, pair: ShapePair, start: RhmStart, params: RhmParams, progress: Progress, curves: Curves
    ) -> PointwiseMaps:
        """The iterations from ``start`` (on decimated copies above ``dense_up_to`` vertices)."""
        if max(pair.mesh_M.n_vertices, pair.mesh_N.n_vertices) > params.dense_up_to:
            return coarse_reversible_harmonic_maps(
                pair, start.maps, params, scaled(progress, 0.3, 1.0), curves, start.anchor
            )
        progress(0.3, "geodesic embedding of the source")
        shape_M = prepare_shape(pair.mesh_M, params)
        progress(0.35, "geodesic embedding of the target")
        shape_N = prepare_shape(pair.mesh_N, params)
        state = self.begin(start.maps, shape_M, shape_N, start.pins, start.anchor)
        self.iterate(state, params, scaled(progress, 0.4, 1.0))
        return PointwiseMaps(p2p_NM=state.NM.p2p, p2p_MN=state.MN.p2p)


REFINER = Rhm()


def reversible_harmonic_maps(
    maps: PointwiseMaps,
    shape_M: _Shape,
    shape_N: _Shape,
    params: RhmParams,
    progress: Progress = no_progress,
    pins: CurvePins | None = None,
    anchor: PointwiseMaps | None = None,
) -> tuple[_Map, _Map, float]:
    """Alternating minimisation from the pointwise maps ``maps``, keeping ``pins`` fixed and every image within
    ``params.anchor_radius`` of its image under ``anchor`` (vertex projection): both maps as they end
    (``MN.p2p`` is ``p2p_MN``), and the last coupling weight."""
    pins = pins or no_pins(len(shape_M.X), len(shape_N.X))
    state = REFINER.iterate(REFINER.begin(maps, shape_M, shape_N, pins, anchor), params, progress)
    return state.MN, state.NM, state.beta


def convert_rhm(
    pair: ShapePair, fmaps: FunctionalMaps, params: RhmParams, progress: Progress = no_progress, curves: Curves = ()
) -> PointwiseMaps:
    """RHM's maps (:meth:`Rhm.convert`)."""
    return REFINER.convert(pair, fmaps, params, progress, curves)


@dataclass(frozen=True)
class _Coarse:
    """A decimated copy of a mesh: ``fine_ids[c]`` is the vertex of the mesh nearest coarse vertex c,
    ``coarse_ids[v]`` the coarse vertex nearest vertex v of the mesh, and ``prolong`` (n x n_coarse) the
    barycentric weights of each vertex's closest point on the copy."""

    mesh: Mesh
    fine_ids: np.ndarray
    coarse_ids: np.ndarray
    prolong: sp.csr_matrix

    @classmethod
    def of(cls, mesh: Mesh, vertex_count: int) -> _Coarse:
        coarse = build_mesh(*decimate(mesh.vertices, mesh.faces, vertex_count), name=f"{mesh.name}-coarse")
        # cKDTree.query is typed for one point or many; with many it answers arrays
        fine_ids = cast(np.ndarray, cKDTree(mesh.vertices).query(coarse.vertices)[1])
        coarse_ids = cast(np.ndarray, cKDTree(coarse.vertices).query(mesh.vertices)[1])
        return cls(coarse, fine_ids, coarse_ids, closest_point_weights(mesh.vertices, coarse.vertices, coarse.faces))

    def path(self, fine_path: np.ndarray) -> np.ndarray:
        """A curve's vertex path on the coarse copy (nearest coarse vertices, repeats dropped)."""
        path = self.coarse_ids[np.asarray(fine_path, dtype=np.int64)]
        return path[np.r_[True, path[1:] != path[:-1]]]


def coarse_reversible_harmonic_maps(
    pair: ShapePair,
    maps: PointwiseMaps,
    params: RhmParams,
    progress: Progress = no_progress,
    curves: Curves = (),
    anchor: PointwiseMaps | None = None,
) -> PointwiseMaps:
    """RHM on decimated copies of both shapes, from ``maps`` (and ``anchor``) carried to them, then one
    projection of every vertex: the embeddings and continuous images of the copies, interpolated to every
    vertex, give the projection step of the last iteration at full resolution (curves pinned, anchored)."""
    progress(0.0, f"decimating both shapes to about {params.coarse_vertices} vertices")
    M, N = _Coarse.of(pair.mesh_M, params.coarse_vertices), _Coarse.of(pair.mesh_N, params.coarse_vertices)
    start, coarse_anchor = _on_copies(maps, M, N), None if anchor is None else _on_copies(anchor, M, N)
    pins = CurvePins.from_curves(M.mesh, N.mesh, [(M.path(path_M), N.path(path_N)) for path_M, path_N in curves])
    progress(0.05, "geodesic embeddings of the decimated shapes")
    shape_M, shape_N = prepare_shape(M.mesh, params), prepare_shape(N.mesh, params)
    MN, NM, beta = reversible_harmonic_maps(
        start, shape_M, shape_N, params, scaled(progress, 0.1, 0.95), pins, coarse_anchor
    )
    progress(0.95, "projecting every vertex")
    X_M, X_N, X_MN, X_NM = M.prolong @ shape_M.X, N.prolong @ shape_N.X, M.prolong @ MN.X, N.prolong @ NM.X
    fine_pins = CurvePins.from_curves(pair.mesh_M, pair.mesh_N, curves)
    p2p_NM = nearest_vertices(X_MN, X_M, X_N, X_NM, params.alpha, beta)
    p2p_MN = nearest_vertices(X_NM, X_N, X_M, X_MN, params.alpha, beta)
    anchor_NM, anchor_MN = (None, None) if anchor is None else (anchor.p2p_NM, anchor.p2p_MN)
    return PointwiseMaps(
        p2p_NM=fine_pins.pin_NM(near_anchor(p2p_NM, anchor_NM, X_M, params.anchor_radius)),
        p2p_MN=fine_pins.pin_MN(near_anchor(p2p_MN, anchor_MN, X_N, params.anchor_radius)),
    )


def _on_copies(maps: PointwiseMaps, M: _Coarse, N: _Coarse) -> PointwiseMaps:
    """``maps`` between the decimated copies: each coarse vertex takes its nearest fine vertex's image."""
    return PointwiseMaps(p2p_NM=M.coarse_ids[maps.p2p_NM[N.fine_ids]], p2p_MN=N.coarse_ids[maps.p2p_MN[M.fine_ids]])


def nearest_vertices(
    back_X: np.ndarray, image_X: np.ndarray, domain_X: np.ndarray, fwd_X: np.ndarray, alpha: float, beta: float
) -> np.ndarray:
    """The vertex projection of :func:`project` from embeddings alone: for each domain vertex, the image vertex
    minimising ``(1 - alpha) |back_X - domain_X|^2 + beta |image_X - fwd_X|^2``."""
    data, queries = projection_embeddings(back_X, image_X, domain_X, fwd_X, alpha, beta)
    return cast(np.ndarray, cKDTree(data).query(queries, workers=-1)[1])  # many queries: an array


def rhm_basis_size(params: RhmParams) -> int:
    """The zoomout start's basis size (none for the nearest-neighbour start)."""
    return REFINER.basis_size(params)


RHM = REFINER.plugin()
