"""The shape pair every map is computed on: source M and target N with their bases.

Direction convention throughout: M is the source, N the target. A functional map ``C_MN`` takes
coefficients on M to coefficients on N; a pointwise map ``p2p_NM[j]`` is the vertex of M for vertex j of N.
"""

from __future__ import annotations

from dataclasses import dataclass

from curvefm.geometry import Mesh
from curvefm.spectral.basis import Basis


@dataclass(frozen=True)
class ShapePair:
    """Both meshes (internal vertex ids) and their bases, which may hold more functions than a map uses."""

    mesh_M: Mesh
    mesh_N: Mesh
    basis_M: Basis
    basis_N: Basis

    @property
    def meshes(self) -> tuple[Mesh, Mesh]:
        return self.mesh_M, self.mesh_N

    def truncated(self, k: int) -> ShapePair:
        """The same meshes with the first ``k`` functions of each basis."""
        return ShapePair(self.mesh_M, self.mesh_N, self.basis_M.truncated(k), self.basis_N.truncated(k))
