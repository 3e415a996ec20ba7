"""Refinement on a vertex sample, converted densely once at the end (ZoomOut's fast variant, Melzi et al. 2019).

Each iteration of ICP or ZoomOut converts functional maps to pointwise maps by nearest neighbours, whose cost
grows with the product of the two vertex counts. On big meshes the refiners therefore iterate on a few
thousand spread samples of each shape: pointwise maps between samples, functional maps fitted by least
squares on the samples (the sampled rows of a basis are not mass-orthonormal). Only the last conversion
matches every vertex. :func:`refinement_samples` decides, from the shapes' sizes, whether to sample.

Map directions follow :mod:`curvefm.pointwise.conversion`: a map from the ``domain``'s rows sends each to a
row of the ``image``; the functional map fitted from it takes coefficients on the image to the domain (as
``C_MN`` for ``p2p_NM``).
"""

from __future__ import annotations

import numpy as np

from curvefm.geometry import Mesh
from curvefm.pointwise.conversion import nearest_orthogonal
from curvefm.pointwise.neighbors import nearest_neighbors
from curvefm.pointwise.refinement import spread_samples
from curvefm.spectral import Basis

#: shapes up to this many vertices are refined on every vertex unless samples are asked for. ZoomOut on samples
#: was within 2% of every vertex at 110k, but up to 17% worse in one direction at 27.5k (the subdivided FAUST
#: pair) and 27% on FAUST itself, so TOSCA-sized shapes (up to 28k) stay dense.
# chosen in docs/decisions.md#refining-big-shapes-on-samples
DENSE_UP_TO = 30_000
#: samples a shape when a bigger one is refined without an explicit count
AUTO_SAMPLES = 4_000
#: vertices of each shape the ``nearest-neighbor`` converter's orthogonal steps iterate on where its search is
#: approximate (big meshes)
# chosen in docs/decisions.md#orthogonal-steps-in-the-conversion
STEP_SAMPLES = 20_000


class VertexRows:
    """The vertices a refiner iterates on, for one shape: all of them (``ids=None``) or samples."""

    def __init__(self, basis: Basis, ids: np.ndarray | None = None):
        self.basis = basis
        self.all = ids is None
        self.ids = np.arange(basis.n_vertices) if ids is None else ids

    def evecs(self, k: int) -> np.ndarray:
        return self.basis.evecs[self.ids, :k]

    @property
    def subset(self) -> np.ndarray | None:
        """The sampled vertex ids, or None for all vertices (as :class:`CurvePins` takes ``rows``)."""
        return None if self.all else self.ids


def refinement_samples(
    mesh_M: Mesh, mesh_N: Mesh, samples: int | None, dense_up_to: int = DENSE_UP_TO
) -> tuple[np.ndarray, np.ndarray] | None:
    """Spread samples ``(ids_M, ids_N)`` to iterate on, or None to iterate on every vertex: ``samples`` of
    each shape where given, else :data:`AUTO_SAMPLES` when a shape has more than ``dense_up_to`` vertices."""
    if samples is None:
        if max(mesh_M.n_vertices, mesh_N.n_vertices) <= dense_up_to:
            return None
        samples = AUTO_SAMPLES
    return spread_samples(mesh_M, samples), spread_samples(mesh_N, samples)


def fit_fmap(
    p2p: np.ndarray, domain: VertexRows, image: VertexRows, k_domain: int, k_image: int | None = None
) -> np.ndarray:
    """The ``k_domain x k_image`` functional map (image -> domain coefficients; ``k_image`` defaults to
    ``k_domain``) pulled back by a pointwise map that sends ``domain.ids[r]`` to vertex ``p2p[r]`` of the
    image. All vertices: ``Psi^T A Phi[p2p]``; samples: least squares on the samples."""
    moved = image.basis.evecs[p2p, : k_image or k_domain]
    if domain.all:
        return domain.evecs(k_domain).T @ (domain.basis.mass[:, None] * moved)
    return np.linalg.lstsq(domain.evecs(k_domain), moved, rcond=None)[0]


def match_rows(
    C: np.ndarray,
    domain: VertexRows,
    image: VertexRows,
    search: str,
    C_back: np.ndarray | None = None,
) -> np.ndarray:
    """The pointwise map from the domain's rows to the image's rows (image vertex ids) induced by ``C``
    (image -> domain coefficients, as ``C_MN`` for a map N -> M) and, where given, by ``C_back`` (domain ->
    image) too, in the embedding of both maps (:func:`curvefm.pointwise.conversion.pointwise_from_both`)."""
    data, queries = image.evecs(C.shape[1]) @ C.T, domain.evecs(C.shape[0])
    if C_back is not None:
        data, queries = np.hstack([data, image.evecs(C.shape[1])]), np.hstack([queries, queries @ C_back.T])
    return image.ids[nearest_neighbors(data, queries, search)]


def area_samples(basis: Basis, count: int) -> VertexRows:
    """``count`` vertices (every vertex where there are fewer), drawn without replacement with probability
    proportional to their area (seed 0, so always the same ones): least squares on them weigh the surface as the
    mass-weighted fit on every vertex does, and drawing costs well under a second at millions of vertices."""
    if count >= basis.n_vertices:
        return VertexRows(basis)
    ids = np.random.default_rng(0).choice(basis.n_vertices, count, replace=False, p=basis.mass / basis.mass.sum())
    return VertexRows(basis, np.sort(ids))


def sampled_orthogonal_steps(
    p2p: np.ndarray, domain: VertexRows, image: VertexRows, k_domain: int, k_image: int, steps: int, search: str
) -> np.ndarray:
    """The functional map (``k_domain x k_image``, image -> domain) of the last of ``steps`` >= 1 orthogonal steps
    (:func:`curvefm.pointwise.conversion.orthogonal_steps`) from ``p2p`` (domain rows -> image vertices), iterated
    between the rows: fit, nearest map with orthonormal columns, match again; the last step's match is left to the
    caller, on every vertex. Each fit is :func:`fit_fmap`'s, its least squares solved once for all the steps."""
    fit = _fit_rows(domain, k_domain)
    C = nearest_orthogonal(fit @ image.basis.evecs[p2p, :k_image])
    for _ in range(steps - 1):
        C = nearest_orthogonal(fit @ image.basis.evecs[match_rows(C, domain, image, search), :k_image])
    return C


def _fit_rows(domain: VertexRows, k: int) -> np.ndarray:
    """The ``k x rows`` matrix :func:`fit_fmap` applies to the image's moved rows: ``Psi^T A`` on every vertex, on
    samples their least squares by the normal equations (area-drawn samples of mass-orthonormal functions are well
    conditioned; 20,000 x 120: 1.2 s against 2.7 s for ``lstsq`` and 5.3 s for ``pinv``, loaded)."""
    if domain.all:
        return (domain.basis.mass[:, None] * domain.evecs(k)).T
    rows = domain.evecs(k)
    return np.linalg.solve(rows.T @ rows, rows.T)
