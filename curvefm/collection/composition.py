"""Maps between two members of a collection, composed through the template.

Pointwise maps are per **file** vertex in file ids, -1 for a vertex of no face: ``P_aT[i]`` is the template vertex
of member a's vertex i, ``P_Tb[j]`` member b's vertex of template vertex j, so ``P_ab = P_Tb[P_aT]``. Functional
maps compose the other way round: ``C_ab = C_Tb @ C_aT`` takes coefficients on a to coefficients on b.
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
    """``C_Tb C_aT``; both in the collection's k (a refiner's larger bases do not enter the stored maps)."""
    return C_Tb @ C_aT
