"""Converter plugin ``nearest-neighbor``: functional maps -> pointwise maps (Ovsjanikov et al. 2012)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from curvefm.fmap import FunctionalMaps
from curvefm.plugins.refinement_params import SearchParams
from curvefm.pointwise import PointwiseMaps, pointwise_from_both, pointwise_from_fmap
from curvefm.progress import Progress, no_progress
from curvefm.registry import ConverterPlugin
from curvefm.spectral import ShapePair


class NearestNeighborParams(SearchParams):
    embedding: Literal["both", "single"] = Field(
        "both",
        description="'both': match in the embedding built from C_MN and C_NM together; 'single': each "
        "direction from its own map only (Ovsjanikov et al. 2012)",
    )


def convert_nearest_neighbor(
    pair: ShapePair, maps: FunctionalMaps, params: NearestNeighborParams, progress: Progress = no_progress
) -> PointwiseMaps:
    M, N = pair.basis_M, pair.basis_N
    progress(0.0, "nearest neighbours N -> M")
    if params.embedding == "both":
        p2p_NM = pointwise_from_both(maps.C_MN, maps.C_NM, M, N, params.search)
        progress(0.5, "nearest neighbours M -> N")
        p2p_MN = pointwise_from_both(maps.C_NM, maps.C_MN, N, M, params.search)
    else:
        p2p_NM = pointwise_from_fmap(maps.C_MN, M, N, params.search)
        progress(0.5, "nearest neighbours M -> N")
        p2p_MN = pointwise_from_fmap(maps.C_NM, N, M, params.search)
    progress(1.0, "done")
    return PointwiseMaps(p2p_NM=p2p_NM, p2p_MN=p2p_MN)


NEAREST_NEIGHBOR = ConverterPlugin(
    name="nearest-neighbor",
    description="Nearest neighbours in the spectral embedding, both directions (Ovsjanikov et al. 2012)",
    Params=NearestNeighborParams,
    run=convert_nearest_neighbor,
    refines=False,
)
