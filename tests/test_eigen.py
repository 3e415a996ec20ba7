"""curvefm.spectral.smallest_eigenpairs against the plain shift-invert eigsh, on a real mesh (lion, 5000 vertices)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh

from curvefm.geometry import cotangent_laplacian, load_mesh
from curvefm.spectral import eigensolver as eigen

K = 40


@pytest.fixture(scope="module")
def lion(shared_data):
    mesh = load_mesh(shared_data / "nonisometric" / "pyfm_cat_lion" / "lion-00.off")
    L, mass = cotangent_laplacian(mesh.vertices / np.sqrt(mesh.area), mesh.faces)
    mass = mass / mass.sum()
    evals, evecs = eigsh(L.tocsc(), K, M=sp.diags(mass).tocsc(), sigma=-0.01)
    order = np.argsort(evals)
    return L, mass, evals[order], evecs[:, order]


@pytest.mark.parametrize("workers", [1, 2, 3], ids=["serial", "two-slices", "three-slices"])
def test_matches_plain_eigsh(lion, workers):
    L, mass, ref_evals, ref_evecs = lion
    evals, evecs = eigen.smallest_eigenpairs(L, mass, K, workers=workers)
    assert evals.shape == (K,) and evecs.shape == (len(mass), K)
    assert np.all(np.diff(evals) >= 0)
    assert abs(evals[0]) < 1e-8 * ref_evals[-1]  # the constant function
    np.testing.assert_allclose(evals[1:], ref_evals[1:], rtol=1e-6, atol=0)
    np.testing.assert_allclose(evecs.T @ (mass[:, None] * evecs), np.eye(K), atol=1e-10)
    # the same eigenvectors up to sign, wherever the eigenvalue is apart from its neighbours
    gaps = np.diff(ref_evals) / ref_evals[1:]
    apart = np.flatnonzero(np.minimum(np.r_[np.inf, gaps], np.r_[gaps, 0.0]) > 1e-2)
    cosines = np.abs(np.einsum("ij,i,ij->j", ref_evecs[:, apart], mass, evecs[:, apart]))
    assert len(apart) > K // 4 and np.all(cosines > 1 - 1e-8)


def test_upper_slice_exact_where_weyl_is_off(lion):
    """Weyl's guess of the slice's shift is 1000 times too low: the inertia count still fixes the indices."""
    L, mass, ref_evals, _ = lion
    scale = 1000.0
    evals, evecs = eigen.index_range(sp.csr_matrix(L) * scale, mass, 25, K, 1e-6)
    np.testing.assert_allclose(evals, ref_evals[25:] * scale, rtol=1e-6)
    np.testing.assert_allclose(evecs.T @ (mass[:, None] * evecs), np.eye(K - 25), atol=1e-10)
