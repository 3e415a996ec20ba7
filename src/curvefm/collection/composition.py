"""Maps between two members of a collection, composed through the template.

Pointwise maps are per **file** vertex in file ids, -1 for a vertex of no face: ``P_aT[i]`` is the template vertex
of member a's vertex i, ``P_Tb[j]`` member b's vertex of template vertex j, so ``P_ab = P_Tb[P_aT]``. Functional
maps compose the other way round: ``C_ab = C_Tb @ C_aT`` takes coefficients on a to coefficients on b.

Members' functional maps may differ in size: the combined energy hands a member's map out at 50 x 50 below 20 curves
and whole (the collection's k) from 20 on. A map is read as the operator that is zero beyond its block, so the
product runs over the template frequencies both maps hold (zero-padding the smaller map and truncating the larger
give the same product), and each member keeps its own size on the outside: ``C_ab`` is ``k_b x k_a``
(docs/decisions.md#composing-maps-of-different-sizes).
"""

from __future__ import annotations

import numpy as np


def compose_pointwise(P_aT: np.ndarray, P_Tb: np.ndarray) -> np.ndarray:
    """``P_Tb[P_aT]``, with -1 wherever a's vertex has no template vertex."""
    composed = np.full(len(P_aT), -1, dtype=np.int64)
    mapped = P_aT >= 0
    composed[mapped] = P_Tb[P_aT[mapped]]
    return composed


def compose_functional(C_aT: np.ndarray, C_Tb: np.ndarray) -> np.ndarray:
    """``C_Tb C_aT`` over the template frequencies both hold: ``k_b x k_a`` whatever sizes the two were handed out
    at (module doc)."""
    shared = min(C_aT.shape[0], C_Tb.shape[1])
    return C_Tb[:, :shared] @ C_aT[:shared, :]
