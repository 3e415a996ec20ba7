"""Functional maps both ways, the correspondence hints a map method works from, and what a solver's maps are."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Hints:
    """Correspondences a map method starts from (internal vertex ids; the shapes are a ``ShapePair``).

    ``curves`` are corresponding vertex paths ``(path_M, path_N)`` with their ``weights`` (empty: all 1);
    ``landmarks`` (m x 2) are corresponding vertices, by default the curves' endpoints (what the paper gives
    the descriptor baselines).
    """

    curves: tuple[tuple[np.ndarray, np.ndarray], ...] = ()
    landmarks: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    weights: tuple[float, ...] = ()

    @classmethod
    def from_curves(cls, curves: Sequence[tuple[np.ndarray, np.ndarray]], weights: Iterable[float] = ()) -> Hints:
        return cls(tuple(curves), curve_endpoints(curves), tuple(weights))


@dataclass(frozen=True)
class FunctionalMaps:
    C_MN: np.ndarray  # (k_N, k_M): coefficients on M -> coefficients on N
    C_NM: np.ndarray  # (k_M, k_N)


@dataclass(frozen=True)
class EffectiveSolve:
    """What a solver's maps are now, whatever its parameters asked: the ``energy`` they minimise, its ``weights`` as
    applied (``alpha`` and the energy's other terms), the ``size`` they are handed out at (size x size), and why, in a
    few words (``summary``, e.g. ``combined; 50 x 50 until curves totalling 6.2 sqrt(area)``) and in full
    (``reason``)."""

    energy: str
    weights: dict[str, float]
    size: int
    summary: str
    reason: str


def curve_endpoints(curves: Iterable[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Distinct ``(vertex on M, vertex on N)`` pairs at the ends of the curves, in order of appearance."""
    pairs = []
    for path_M, path_N in curves:
        for end in (0, -1):
            pair = (int(path_M[end]), int(path_N[end]))
            if pair not in pairs:
                pairs.append(pair)
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)
