"""Converter plugin ``nearest-neighbor``: functional maps -> pointwise maps (Ovsjanikov et al. 2012)."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from curvefm.fmap import FunctionalMaps
from curvefm.geometry import Mesh
from curvefm.plugins.refinement_params import SearchParams
from curvefm.pointwise import (
    STEP_SAMPLES,
    PointwiseMaps,
    area_samples,
    edge_stretch,
    match_rows,
    orthogonal_steps,
    pointwise_from_both,
    pointwise_from_fmap,
    room_for_steps,
    sampled_orthogonal_steps,
    stepped_size,
    uses_approximate,
)
from curvefm.progress import Progress, no_progress
from curvefm.registry import ConverterPlugin
from curvefm.spectral import Basis, ShapePair

# chosen in docs/decisions.md#orthogonal-steps-in-the-conversion
ORTHOGONAL_STEPS = 3


class NearestNeighborParams(SearchParams):
    embedding: Literal["auto", "both", "single"] = Field(
        "auto",
        description="'both': match in the embedding built from C_MN and C_NM together; 'single': each "
        "direction from its own map only (Ovsjanikov et al. 2012); 'auto': both candidates, and per direction the "
        "one whose images of the edges stretch least (no ground truth needed); 'both' where the search is "
        "approximate (big meshes), as a second candidate would double the conversion there",
    )
    orthogonal_steps: int = Field(
        ORTHOGONAL_STEPS,
        ge=0,
        le=50,
        description="orthogonal (ICP) steps at the functional map's own size after the nearest neighbours, each "
        "direction: the map fitted to the pointwise map, made orthonormal, matched again; they sharpen the map the "
        "curves determine without going beyond its frequencies; a map of the basis's size is converted from its "
        "leading block, leaving them 30 functions of the basis to fit against. Where the search is approximate (big "
        f"meshes) all but the last step's match run between {STEP_SAMPLES:,} vertices of each shape drawn by area",
    )


def convert_nearest_neighbor(
    pair: ShapePair, maps: FunctionalMaps, params: NearestNeighborParams, progress: Progress = no_progress
) -> PointwiseMaps:
    progress(0.0, "nearest neighbours N -> M")
    p2p_NM = _one_direction(pair.mesh_N, pair.mesh_M, maps.C_MN, maps.C_NM, pair.basis_M, pair.basis_N, params)
    progress(0.5, "nearest neighbours M -> N")
    p2p_MN = _one_direction(pair.mesh_M, pair.mesh_N, maps.C_NM, maps.C_MN, pair.basis_N, pair.basis_M, params)
    progress(1.0, "done")
    return PointwiseMaps(p2p_NM=p2p_NM, p2p_MN=p2p_MN)


def _one_direction(
    mesh_from: Mesh,
    mesh_to: Mesh,
    C_forward: np.ndarray,
    C_back: np.ndarray,
    basis_to: Basis,
    basis_from: Basis,
    params: NearestNeighborParams,
) -> np.ndarray:
    """The map from ``mesh_from`` to ``mesh_to`` (a vertex of ``mesh_to`` per vertex): ``C_forward`` carries
    functions from ``mesh_to`` to ``mesh_from``, ``C_back`` the other way."""
    exact = not uses_approximate(mesh_to.n_vertices, mesh_from.n_vertices)
    if params.orthogonal_steps > 0:
        C_forward, C_back = room_for_steps(C_forward, C_back, basis_from)
    k_from, k_to = C_forward.shape
    if not exact and params.orthogonal_steps > 0 and stepped_size(k_from, basis_from) > k_from:
        return _stepped_on_samples(C_forward, C_back, basis_to, basis_from, params)
    embedding = "both" if params.embedding == "auto" and not exact else params.embedding
    candidates = []
    if embedding in ("auto", "both"):
        candidates.append(pointwise_from_both(C_forward, C_back, basis_to, basis_from, params.search))
    if embedding in ("auto", "single"):
        candidates.append(pointwise_from_fmap(C_forward, basis_to, basis_from, params.search))
    p2p = min(candidates, key=lambda p2p: edge_stretch(mesh_from, mesh_to, p2p))
    if not exact:
        return p2p
    return orthogonal_steps(p2p, basis_to, basis_from, k_to, k_from, params.orthogonal_steps, params.search)


def _stepped_on_samples(
    C_forward: np.ndarray, C_back: np.ndarray, basis_to: Basis, basis_from: Basis, params: NearestNeighborParams
) -> np.ndarray:
    """Where the search is approximate (big meshes): the first match and all but the last orthogonal step's between
    :data:`~curvefm.pointwise.STEP_SAMPLES` vertices of each shape, drawn by area, then one search on every vertex
    with the last step's map (docs/decisions.md#orthogonal-steps-in-the-conversion)."""
    rows_from, rows_to = area_samples(basis_from, STEP_SAMPLES), area_samples(basis_to, STEP_SAMPLES)
    both = C_back if params.embedding != "single" else None
    p2p = match_rows(C_forward, rows_from, rows_to, params.search, both)
    k_from, k_to = C_forward.shape
    k_image = stepped_size(k_from, basis_from)
    C = sampled_orthogonal_steps(p2p, rows_from, rows_to, k_image, k_to, params.orthogonal_steps, params.search)
    return pointwise_from_fmap(C, basis_to, basis_from, params.search)


NEAREST_NEIGHBOR = ConverterPlugin(
    name="nearest-neighbor",
    description="Nearest neighbours in the spectral embedding, both directions (Ovsjanikov et al. 2012)",
    Params=NearestNeighborParams,
    run=convert_nearest_neighbor,
    refines=False,
)
