"""Basis plugin ``laplace-beltrami``: the first k eigenfunctions of the Laplace-Beltrami operator.

The computation is the core's default basis (:func:`curvefm.spectral.laplace_beltrami_basis`), which the store and
the refiners call directly; this plugin makes it one basis among those a user can choose by name.
"""

from __future__ import annotations

from curvefm.registry import BasisPlugin
from curvefm.spectral import (
    DEFAULT_BASIS,
    LaplaceBeltramiParams,
    laplace_beltrami_basis,
    laplace_beltrami_storage_params,
)

LAPLACE_BELTRAMI = BasisPlugin(
    name=DEFAULT_BASIS,
    description="First k eigenpairs of the Laplace-Beltrami operator (shift-invert, or multiresolution on big "
    "meshes), on the unit-area mesh",
    Params=LaplaceBeltramiParams,
    run=laplace_beltrami_basis,
    storage_params=laplace_beltrami_storage_params,
)
