"""The multiresolution basis (curvefm.spectral.multires) on a scan-like mesh: FAUST tr_reg_000 subdivided
once (27,554 vertices, generated here), against the exact solver."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from curvefm.geometry import cotangent_laplacian, load_mesh
from curvefm.spectral import multires, multires_eigenpairs, smallest_eigenpairs
from curvefm.spectral.multires import prolongation

K = 60


@pytest.fixture(scope="module")
def subdivided(shared_data):
    mesh = load_mesh(shared_data / "faust" / "tr_reg_000.off")
    vertices, faces = trimesh.remesh.subdivide(mesh.vertices / np.sqrt(mesh.area), mesh.faces)
    L, mass = cotangent_laplacian(vertices, faces)
    return vertices, faces, L, mass / mass.sum()


def test_eigenvalues_within_one_percent_and_orthonormal(subdivided):
    vertices, faces, L, mass = subdivided
    exact, _ = smallest_eigenpairs(L, mass, K, workers=1)
    evals, evecs = multires_eigenpairs(L, mass, vertices, faces, K, coarse_vertices=3000)
    assert evecs.shape == (len(mass), K)
    relative = np.abs(evals[1:] - exact[1:]) / exact[1:]
    assert relative.max() <= 0.01, relative.max()
    assert np.all(evals[1:] >= exact[1:] * (1 - 1e-9))  # Ritz values bound the exact ones from above
    np.testing.assert_allclose(evecs.T @ (mass[:, None] * evecs), np.eye(K), atol=1e-8)
    assert abs(evals[0]) < 1e-8 * evals[-1]


def test_prolongation_is_a_partition_of_unity(subdivided):
    vertices, faces, _, _ = subdivided
    prolong = prolongation(vertices, faces, 2000)
    assert 1000 < prolong.shape[1] <= 2200
    np.testing.assert_allclose(np.asarray(prolong.sum(axis=1)).ravel(), 1.0, atol=1e-6)
    assert prolong.min() >= 0 and np.all(np.diff(prolong.indptr) <= 3)


def test_blocks_do_not_change_the_basis(subdivided, monkeypatch):
    """Scans are refined a few columns and rows at a time (to bound memory): block sizes that divide neither the
    columns nor the rows give the basis of one block, two refinement steps included."""
    vertices, faces, L, mass = subdivided
    whole = multires_eigenpairs(L, mass, vertices, faces, 20, coarse_vertices=1500, refine_steps=2)
    monkeypatch.setattr(multires, "SOLVE_COLUMNS", 7)
    monkeypatch.setattr(multires, "ROW_BLOCK", 1000)
    blocked = multires_eigenpairs(L, mass, vertices, faces, 20, coarse_vertices=1500, refine_steps=2)
    np.testing.assert_allclose(blocked[0], whole[0], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.abs(blocked[1]), np.abs(whole[1]), atol=1e-7)


def test_rayleigh_ritz_leaves_out_a_direction_that_shift_invert_made_dependent(subdivided):
    """Two columns parallel to rounding (shift-invert can do that) made the projected mass matrix indefinite and
    the generalised eigensolver fail; the dependent direction is left out and the Ritz pairs stay those of the span."""
    vertices, faces, L, mass = subdivided
    _, evecs = smallest_eigenpairs(L, mass, 12, workers=1)
    distinct = evecs[:, :10].copy()
    doubled = np.hstack([distinct[:, :2], distinct[:, 1:2] * (1 + 1e-15), distinct[:, 2:]])
    evals, rotation = multires._rayleigh_ritz(L, mass, doubled)
    expected, _ = multires._rayleigh_ritz(L, mass, distinct)
    assert rotation.shape == (11, 10)
    np.testing.assert_allclose(evals, expected, rtol=1e-8, atol=1e-10)
    ritz = doubled @ rotation
    np.testing.assert_allclose(ritz.T @ (mass[:, None] * ritz), np.eye(10), atol=1e-8)
