"""Agreement between two annotators of one member (double annotation), measured on the member.

Each annotator's session maps the template to the member. Their pointwise maps are compared at the same template
vertices (``rows``, internal ids): for each, the graph-geodesic distance on the member between the two annotators'
images, averaged and divided by sqrt(area of the member). Their curves are compared where both answered a template
curve: the geodesic distance between their starts and between their ends on the member, divided alike. Images on
different components of the member have no distance: they are counted (``unreachable``), left out of the mean, and
an endpoint distance is then None. Per annotator (:func:`by_annotator`): the mean of their pairs' distances over
the members they share with another annotator, so that one who disagrees with everyone stands out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from curvefm.geometry import Mesh, pair_geodesic_distances


@dataclass(frozen=True)
class Annotated:
    """One annotator's answer on a member: ``p2p[r]`` is the member vertex (internal id) of the r-th compared
    template vertex; ``ends[t]`` the member vertices (internal ids) where its answer to template curve t starts
    and ends."""

    annotator: str | None
    session: str
    p2p: np.ndarray
    ends: dict[str, tuple[int, int]]


@dataclass(frozen=True)
class CurveEnds:
    template_curve: str
    start: float | None
    end: float | None


@dataclass(frozen=True)
class PairAgreement:
    a: Annotated
    b: Annotated
    map_distance: float | None
    """Mean geodesic distance between the two maps' images, by sqrt(area of the member) (None: all unreachable)."""
    unreachable: int
    """Compared template vertices whose two images lie on different components of the member."""
    curves: list[CurveEnds]
    """Per template curve both answered: the distance between the starts and between the ends, by sqrt(area)."""

    @property
    def endpoint_distance(self) -> float | None:
        """The mean over both ends of every curve both answered (None: none to compare)."""
        ends = [d for c in self.curves for d in (c.start, c.end) if d is not None]
        return float(np.mean(ends)) if ends else None


def agreement(a: Annotated, b: Annotated, member: Mesh) -> PairAgreement:
    """How far apart ``a``'s and ``b``'s answers on ``member`` lie (module doc)."""
    if a.p2p.shape != b.p2p.shape:
        raise ValueError("both maps must be compared at the same template vertices")
    scale = float(np.sqrt(member.area))
    shared = sorted(a.ends.keys() & b.ends.keys())
    ends_a = np.array([a.ends[t] for t in shared], dtype=np.int64).reshape(-1)
    ends_b = np.array([b.ends[t] for t in shared], dtype=np.int64).reshape(-1)
    distances = pair_geodesic_distances(member, np.concatenate([a.p2p, ends_a]), np.concatenate([b.p2p, ends_b]))
    on_map, on_ends = distances[: len(a.p2p)], distances[len(a.p2p) :].reshape(-1, 2) / scale
    reached = on_map[np.isfinite(on_map)]
    mean = float(reached.mean() / scale) if reached.size else None
    curves = [CurveEnds(t, _finite(start), _finite(end)) for t, (start, end) in zip(shared, on_ends, strict=True)]
    return PairAgreement(a, b, mean, int(on_map.size - reached.size), curves)


@dataclass(frozen=True)
class AnnotatorAgreement:
    annotator: str
    members: int
    """Members the annotator shares with another annotator (each with a pair compared)."""
    map_distance: float | None
    """The mean map distance of their pairs with the other annotators (None: none to compare)."""
    endpoint_distance: float | None


def by_annotator(pairs: list[tuple[str, PairAgreement]]) -> list[AnnotatorAgreement]:
    """Per named annotator, by name, from ``(member, pair)``: the members they share and their pairs' means."""
    shared: dict[str, list[tuple[str, PairAgreement]]] = {}
    for member, pair in pairs:
        for annotator in {pair.a.annotator, pair.b.annotator} - {None}:
            shared.setdefault(str(annotator), []).append((member, pair))
    return [
        AnnotatorAgreement(
            annotator,
            len({member for member, _ in theirs}),
            mean_of_known([pair.map_distance for _, pair in theirs]),
            mean_of_known([pair.endpoint_distance for _, pair in theirs]),
        )
        for annotator, theirs in sorted(shared.items())
    ]


def mean_of_known(values: list[float | None]) -> float | None:
    """The mean of the values that are not None (None: there are none)."""
    known = [v for v in values if v is not None]
    return float(np.mean(known)) if known else None


def _finite(distance: float) -> float | None:
    return float(distance) if np.isfinite(distance) else None
