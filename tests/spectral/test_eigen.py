"""curvefm.spectral.smallest_eigenpairs against the plain shift-invert eigsh, on real meshes: the lion (5000
vertices) and TOSCA's centaur (15,768), with CHOLMOD and with SuperLU (the fallback without scikit-sparse)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh
from support.ci import unavailable

from curvefm.geometry import cotangent_laplacian, load_mesh
from curvefm.spectral import eigensolver as eigen

K = 40
MESHES = {"lion": "nonisometric/pyfm_cat_lion/lion-00.off", "centaur": "tosca/centaur0.off"}


@pytest.fixture(scope="module", params=sorted(MESHES))
def mesh_problem(request, shared_data):
    mesh = load_mesh(shared_data / MESHES[request.param])
    L, mass = cotangent_laplacian(mesh.vertices / np.sqrt(mesh.area), mesh.faces)
    mass = mass / mass.sum()
    evals, evecs = eigsh(L.tocsc(), K, M=sp.diags(mass).tocsc(), sigma=-0.01)
    order = np.argsort(evals)
    return L, mass, evals[order], evecs[:, order]


@pytest.fixture(params=["cholmod", "superlu"])
def factorisation(request, monkeypatch):
    if request.param == "cholmod" and eigen.cholmod is None:
        unavailable("scikit-sparse is not installed: CHOLMOD is optional (scripts/setup.sh installs it)")
    if request.param == "superlu":
        monkeypatch.setattr(eigen, "cholmod", None)
    return request.param


@pytest.mark.parametrize("workers", [1, 2, 3], ids=["serial", "two-slices", "three-slices"])
def test_matches_plain_eigsh(mesh_problem, factorisation, workers):
    L, mass, ref_evals, ref_evecs = mesh_problem
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


def test_thick_restarts_keep_the_basis_bounded(mesh_problem, monkeypatch):
    """A Krylov basis of a little more than the wanted vectors: several restarts, the same eigenpairs."""
    L, mass, ref_evals, _ = mesh_problem
    s = np.sqrt(mass)
    factor = eigen.shifted_factor(sp.csr_matrix(L), mass, eigen.SIGMA)
    restarts = []

    def op(x):
        return s[:, None] * factor.solve(np.asfortranarray(s[:, None] * x))

    original = eigen._thick_restart

    def counted(*args, **kwargs):
        restarts.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(eigen, "_thick_restart", counted)
    theta, y = eigen.block_lanczos(op, len(mass), n_top=K, n_bottom=0, tol=1e-6, max_dim=K + 64)
    evals = np.sort(eigen.SIGMA + 1.0 / theta)
    assert len(restarts) >= 2
    np.testing.assert_allclose(evals[1:], ref_evals[1:], rtol=1e-6)
    np.testing.assert_allclose(y.T @ y, np.eye(K), atol=1e-10)


def test_upper_slice_exact_where_weyl_is_off(mesh_problem, factorisation):
    """Weyl's guess of the slice's shift is 1000 times too low: the inertia count still fixes the indices."""
    L, mass, ref_evals, _ = mesh_problem
    scale = 1000.0
    evals, evecs = eigen.index_range(sp.csr_matrix(L) * scale, mass, 25, K, 1e-6)
    np.testing.assert_allclose(evals, ref_evals[25:] * scale, rtol=1e-6)
    np.testing.assert_allclose(evecs.T @ (mass[:, None] * evecs), np.eye(K - 25), atol=1e-10)
