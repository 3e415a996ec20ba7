"""Basis plugin ``laplace-beltrami``: the first k eigenfunctions of the Laplace-Beltrami operator."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from curvefm.geometry import Mesh, cotangent_laplacian, robust_laplacian
from curvefm.progress import Progress, no_progress
from curvefm.registry import BasisPlugin
from curvefm.spectral import Basis, check_k, smallest_eigenpairs


class LaplaceBeltramiParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    laplacian: Literal["cotangent", "robust"] = Field(
        "cotangent",
        description="'cotangent': cotangent weights with lumped mass; 'robust': intrinsic-Delaunay "
        "Laplacian of Sharp & Crane 2020, for poor triangulations",
    )


def compute_laplace_beltrami(
    mesh: Mesh, k: int, params: LaplaceBeltramiParams, progress: Progress = no_progress
) -> Basis:
    check_k(k, mesh.n_vertices, mesh.name)
    progress(0.0, "building the Laplacian")
    vertices = mesh.vertices / np.sqrt(mesh.area)  # unit total area: see curvefm.spectral.basis
    build = robust_laplacian if params.laplacian == "robust" else cotangent_laplacian
    L, mass = build(vertices, mesh.faces)
    mass = mass / mass.sum()
    progress(0.05, f"computing {k} eigenpairs of a {mesh.n_vertices}-vertex mesh")
    evals, evecs = smallest_eigenpairs(L, mass, k)
    progress(1.0, "basis ready")
    return Basis(np.maximum(evals, 0.0), evecs, mass)


LAPLACE_BELTRAMI = BasisPlugin(
    name="laplace-beltrami",
    description="First k eigenpairs of the Laplace-Beltrami operator (shift-invert), on the unit-area mesh",
    Params=LaplaceBeltramiParams,
    run=compute_laplace_beltrami,
)
