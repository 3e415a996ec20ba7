"""The default basis, ``laplace-beltrami``: the first k eigenpairs of the Laplace-Beltrami operator of the mesh
scaled to unit area (:mod:`curvefm.spectral.basis`), from the exact eigensolver or, on big meshes, the
multiresolution one.

The core computes it here directly (the store, refiners that need a larger basis); the ``laplace-beltrami``
basis plugin (:mod:`curvefm.plugins.bases`) wraps the same function, so a user can name it, or another basis
plugin, where a basis is chosen by name.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from curvefm.geometry import Mesh, cotangent_laplacian, robust_laplacian
from curvefm.progress import Progress, no_progress
from curvefm.spectral.basis import Basis, check_k
from curvefm.spectral.eigensolver import smallest_eigenpairs
from curvefm.spectral.multires import multires_eigenpairs

DEFAULT_BASIS = "laplace-beltrami"
"""The name the default basis is stored and chosen under (the basis plugin's name)."""
# chosen in docs/decisions.md#eigensolver
MULTIRES_MIN_VERTICES = 60_000  # at 110k the multiresolution basis takes 0.66x the exact solver's time


class LaplaceBeltramiParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    laplacian: Literal["cotangent", "robust"] = Field(
        "cotangent",
        description="'cotangent': cotangent weights with lumped mass; 'robust': intrinsic-Delaunay "
        "Laplacian of Sharp & Crane 2020, for poor triangulations",
    )
    method: Literal["auto", "exact", "multires"] = Field(
        "auto",
        description="'exact': shift-invert block Lanczos (eigenvalues to 1e-6); 'multires': eigenpairs of a "
        "decimated mesh prolonged and refined on the full one (eigenvalue error about 1e-4, measured <= 1%); "
        f"'auto': multires from {MULTIRES_MIN_VERTICES} vertices on, else exact",
    )


def laplace_beltrami_basis(
    mesh: Mesh, k: int, params: LaplaceBeltramiParams | None = None, progress: Progress = no_progress
) -> Basis:
    """The first ``k`` Laplace-Beltrami eigenpairs of ``mesh`` at unit area (``params``: defaults if None)."""
    params = params or LaplaceBeltramiParams()
    check_k(k, mesh.n_vertices, mesh.name)
    progress(0.0, "building the Laplacian")
    vertices = mesh.vertices / np.sqrt(mesh.area)  # unit total area: see curvefm.spectral.basis
    build = robust_laplacian if params.laplacian == "robust" else cotangent_laplacian
    L, mass = build(vertices, mesh.faces)
    mass = mass / mass.sum()
    multires = params.method == "multires" or (params.method == "auto" and mesh.n_vertices >= MULTIRES_MIN_VERTICES)
    progress(0.05, f"computing {k} {'approximate ' if multires else ''}eigenpairs of a {mesh.n_vertices}-vertex mesh")
    if multires:
        evals, evecs = multires_eigenpairs(L, mass, vertices, mesh.faces, k)
    else:
        evals, evecs = smallest_eigenpairs(L, mass, k)
    progress(1.0, "basis ready")
    return Basis(np.maximum(evals, 0.0), evecs, mass)


def laplace_beltrami_storage_params(params: LaplaceBeltramiParams) -> dict[str, Any]:
    """The parameters a stored basis is filed under. ``method = auto`` is left out: bases stored before the
    parameter existed (all exact) are found under it."""
    return params.model_dump(exclude={"method"} if params.method == "auto" else None)
