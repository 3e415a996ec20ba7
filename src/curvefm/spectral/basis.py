"""Laplace-Beltrami eigenbases.

A :class:`Basis` always describes the mesh **scaled to unit total area**: eigenvalues are multiplied by the
mesh area and eigenvectors by its square root. That makes eigenvalues, curve restrictions and functional maps
independent of the units a mesh was modelled in. ``mass`` is the lumped vertex area of the unit-area mesh
(it sums to 1) and the eigenvectors are orthonormal under it: ``evecs.T @ (mass[:, None] * evecs) == I``.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

from curvefm.errors import Conflict, InvalidInput

DEFAULT_K = 120  # basis and map size, the paper's; chosen in docs/decisions.md#map-sizes


@dataclass(frozen=True, eq=False)
class Basis:
    evals: np.ndarray  # (k,) ascending, >= 0
    evecs: np.ndarray  # (n, k), mass-orthonormal
    mass: np.ndarray  # (n,) lumped vertex areas, summing to 1

    @property
    def k(self) -> int:
        return len(self.evals)

    @property
    def n_vertices(self) -> int:
        return self.evecs.shape[0]

    def truncated(self, k: int) -> Basis:
        if k > self.k:
            raise InvalidInput(f"asked for {k} basis functions but this basis has only {self.k}")
        return Basis(self.evals[:k], np.ascontiguousarray(self.evecs[:, :k]), self.mass)

    def project(self, values: np.ndarray) -> np.ndarray:
        """Coefficients of per-vertex functions: ``evecs.T @ (mass * values)``."""
        values = np.asarray(values, dtype=np.float64)
        weighted = self.mass[:, None] * values.reshape(len(self.mass), -1)
        return (self.evecs.T @ weighted).reshape((self.k,) + values.shape[1:])

    def to_bytes(self) -> bytes:
        buffer = io.BytesIO()
        np.savez(buffer, evals=self.evals, evecs=self.evecs, mass=self.mass)
        return buffer.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes) -> Basis:
        with np.load(io.BytesIO(data)) as z:
            return cls(z["evals"], z["evecs"], z["mass"])


def max_k(n_vertices: int) -> int:
    """Largest k the shift-invert eigensolver can deliver for a mesh of this size."""
    return max(n_vertices - 2, 0)


def check_k(k: int, n_vertices: int, name: str = "") -> None:
    if not isinstance(k, int | np.integer) or k < 1:
        raise InvalidInput(f"k must be a positive integer, got {k!r}")
    if k > max_k(n_vertices):
        raise Conflict(
            f"k = {k} is too large for mesh '{name}' with {n_vertices} vertices (at most {max_k(n_vertices)})"
        )
