"""Parameters the converters share: the nearest-neighbour search, and for the refiners the vertices they
iterate on (every vertex, or samples converted densely once at the end: :mod:`curvefm.pointwise.sampled`)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from curvefm.pointwise import APPROXIMATE_FROM_PAIRS, AUTO_SAMPLES, DENSE_UP_TO, Search


def curve_interior_weight_field(default: float) -> Any:
    """The refiners' ``curve_interior_weight`` parameter, with its default."""
    return Field(
        default,
        ge=0,
        le=1,
        description="how much each fit trusts the arc-length partners of the curves' inner vertices (0: not at all; "
        "the curves' ends are always pinned; docs/decisions.md#curve-pins)",
    )


class SearchParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    search: Search = Field(
        "auto",
        description="nearest-neighbour search: 'exact' (faiss IndexFlatL2), 'blocked' (exact, numpy matrix "
        "products), 'approximate' (faiss inverted file, recall >= 99%), or 'auto': approximate from "
        f"{APPROXIMATE_FROM_PAIRS:,} data rows x queries on",
    )


class SampledRefinementParams(SearchParams):
    samples: int | None = Field(
        None,
        ge=2,
        le=10**6,
        description="iterate on this many farthest-point samples per shape and match every vertex once at the "
        f"end (ZoomOut's fast variant); null: every vertex up to dense_up_to vertices, {AUTO_SAMPLES} samples above",
    )
    dense_up_to: int = Field(
        DENSE_UP_TO,
        ge=0,
        le=10**9,
        description="with samples null, shapes with more vertices than this are refined on samples",
    )
    curve_interior_weight: float = curve_interior_weight_field(0.0)
