"""The per-column systems of a map update (curvefm.fmap.column_solve) against a plain float64 reference."""

import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from curvefm.errors import CurvefmError, InternalError
from curvefm.fmap import column_solve, solve_both
from curvefm.fmap.column_solve import Prior, column_diagonals, column_ridge, solve_columns


def reference(G, B, lam_rows, lam_cols, alpha):
    """One ``np.linalg.solve`` (LU) per column, same ridge."""
    E = column_diagonals(G, lam_rows, lam_cols, alpha)
    A = np.repeat(G[None], B.shape[1], axis=0)
    A[:, np.arange(len(G)), np.arange(len(G))] += E.T
    return np.linalg.solve(A, B.T[:, :, None])[:, :, 0].T


def relative_error(C, C_ref):
    return np.abs(C - C_ref).max() / np.abs(C_ref).max()


def backward_error(G, B, C, lam_rows, lam_cols, alpha):
    """Largest normwise backward error over the columns: ||b - A c|| / (||A|| ||c|| + ||b||)."""
    E = column_diagonals(G, lam_rows, lam_cols, alpha)
    R = B - G @ C - E * C
    norm_A = np.linalg.norm(G, 2) + E.max(axis=0)
    denominator = norm_A * np.linalg.norm(C, axis=0) + np.linalg.norm(B, axis=0)
    return float(np.max(np.linalg.norm(R, axis=0) / denominator))


def spectrum(k, rng):
    lam = np.sort(np.r_[0.0, rng.uniform(0, 1, k - 1)])
    return lam / lam[-1]


def curve_like(k, n_curves, seed=0, samples=100):
    """``(G_N, B, lam_N, lam_M)`` shaped like real curve constraints: oscillating basis functions sampled
    along a curve. One curve gives a rank-deficient ``G`` (about 50 of 120 directions) and systems with
    condition numbers up to ~1e9, as the FAUST meshes do."""
    rng = np.random.default_rng(seed)
    lam_N, lam_M = spectrum(k, rng), spectrum(k, rng)
    t = np.linspace(0, 1, samples)[:, None]

    def sampled(lam, phase):
        return np.sqrt(2) * np.cos(4 * np.pi * np.sqrt(lam * k) * t + phase)

    G, B = np.zeros((k, k)), np.zeros((k, k))
    for _ in range(n_curves):
        phase = rng.uniform(0, 2 * np.pi, k)
        psi, phi = sampled(lam_N, phase), sampled(lam_M, phase + 0.1 * rng.standard_normal(k))
        G += psi.T @ psi
        B += psi.T @ phi
    return G / (samples * n_curves), B / (samples * n_curves), lam_N, lam_M


@pytest.mark.parametrize("alpha", [0.01, 1.0, 100.0])
def test_random_spd_matches_reference(alpha):
    rng = np.random.default_rng(1)
    k, n = 40, 33
    X = rng.standard_normal((2 * k, k))
    G = X.T @ X / (2 * k)
    B = rng.standard_normal((k, n))
    lam_rows, lam_cols = spectrum(k, rng), spectrum(n, rng)
    C = solve_columns(G, B, lam_rows, lam_cols, alpha)
    assert C.shape == (k, n)
    assert relative_error(C, reference(G, B, lam_rows, lam_cols, alpha)) < 1e-12


@pytest.mark.parametrize(("n_curves", "alpha"), [(1, 0.01), (1, 1.0), (3, 0.1), (3, 100.0)])
def test_ill_conditioned_curve_systems_match_reference(n_curves, alpha):
    G, B, lam_N, lam_M = curve_like(120, n_curves)
    E = column_diagonals(G, lam_N, lam_M, alpha)
    eigenvalues = [np.linalg.eigvalsh(G + np.diag(E[:, j])) for j in range(0, 120, 10)]
    assert max(ev[-1] / ev[0] for ev in eigenvalues) > 1e5  # as badly conditioned as real inputs
    C = solve_columns(G, B, lam_N, lam_M, alpha)
    assert relative_error(C, reference(G, B, lam_N, lam_M, alpha)) < 1e-8
    assert backward_error(G, B, C, lam_N, lam_M, alpha) < 1e-14


def test_directions_without_information_stay_solvable():
    """Column j has no constraint along e_i when G e_i = 0 and lam_rows[i] == lam_cols[j]: only the ridge
    keeps the system regular. With a diagonal G every system is diagonal and the solution is known."""
    k = 12
    g = np.linspace(0.5, 2.0, k)
    g[[2, 7]] = 0.0
    G = np.diag(g)
    lam = np.linspace(0, 1, k)
    rng = np.random.default_rng(3)
    B = rng.standard_normal((k, k))
    B[2, 2] = B[7, 7] = 0.0  # no information: a consistent right-hand side
    alpha = 0.3
    C = solve_columns(G, B, lam, lam, alpha)
    expected = B / (g[:, None] + alpha * (lam[:, None] - lam[None, :]) ** 2 + column_ridge(G, lam, lam, alpha))
    assert np.isfinite(C).all()
    np.testing.assert_allclose(C, expected, rtol=1e-12, atol=0)


def test_no_curves_and_no_commutativity_gives_zero():
    k = 6
    lam = np.linspace(0, 1, k)
    C = solve_columns(np.zeros((k, k)), np.zeros((k, k)), lam, lam, 0.0)
    assert np.array_equal(C, np.zeros((k, k)))


def test_both_directions_threads_and_rectangular_maps():
    rng = np.random.default_rng(4)
    G_N, B, lam_N, lam_M = curve_like(50, 2, seed=5)
    G_M, _, _, _ = curve_like(50, 2, seed=6)
    G_M, B, lam_M = G_M[:40, :40], B[:, :40], lam_M[:40]  # k_N = 50, k_M = 40
    alpha = float(rng.uniform(0.1, 10))
    with ThreadPoolExecutor(1) as executor:
        C_MN, C_NM = solve_both(G_N, G_M, B, lam_N, lam_M, alpha, executor=executor)
        split = solve_columns(G_N, B, lam_N, lam_M, alpha, executor=executor)
    assert C_MN.shape == (50, 40) and C_NM.shape == (40, 50)
    assert np.array_equal(C_MN, solve_columns(G_N, B, lam_N, lam_M, alpha))
    assert np.array_equal(C_NM, solve_columns(G_M, B.T, lam_M, lam_N, alpha))
    assert np.array_equal(C_MN, split)
    one_after_the_other = solve_both(G_N, G_M, B, lam_N, lam_M, alpha)  # no executor
    assert np.array_equal(one_after_the_other[0], C_MN) and np.array_equal(one_after_the_other[1], C_NM)
    assert relative_error(C_NM, reference(G_M, B.T, lam_M, lam_N, alpha)) < 1e-10


def test_a_prior_pulls_its_block_and_leaves_the_callers_arrays_alone():
    G_N, B, lam_N, lam_M = curve_like(50, 1, seed=7)
    G_M, _, _, _ = curve_like(50, 1, seed=8)
    C0_MN, C0_NM = np.random.default_rng(9).standard_normal((2, 20, 20))
    priors = (Prior(C0_MN, 3.0), Prior(C0_NM, 3.0))
    B_before = B.copy()
    with ThreadPoolExecutor(1) as executor:  # both directions at once: a shared right-hand side must stay intact
        C_MN, C_NM = solve_both(G_N, G_M, B, lam_N, lam_M, 1.0, priors=priors, executor=executor)
    assert np.array_equal(B, B_before)
    for C, G, rhs, rows, cols, C0 in ((C_MN, G_N, B, lam_N, lam_M, C0_MN), (C_NM, G_M, B.T, lam_M, lam_N, C0_NM)):
        E = column_diagonals(G, rows, cols, 1.0)  # the prior as the reference sees it: on the leading block
        E[:20, :20] += 3.0
        wanted = np.array(rhs)
        wanted[:20, :20] += 3.0 * C0
        A = np.repeat(G[None], rhs.shape[1], axis=0)
        A[:, np.arange(50), np.arange(50)] += E.T
        assert relative_error(C, np.linalg.solve(A, wanted.T[:, :, None])[:, :, 0].T) < 1e-10
    without = solve_columns(G_N, B, lam_N, lam_M, 1.0)
    assert np.linalg.norm(C_MN[:20, :20] - C0_MN) < np.linalg.norm(without[:20, :20] - C0_MN)


def test_f2py_fallback_gives_the_same_solution(monkeypatch):
    G, B, lam_N, lam_M = curve_like(60, 2, seed=7)
    fast = solve_columns(G, B, lam_N, lam_M, 0.5)
    monkeypatch.setattr(column_solve, "_DPOSV", None)
    slow_MN, _ = solve_both(G, G, B, lam_N, lam_M, 0.5)
    np.testing.assert_allclose(slow_MN, fast, rtol=0, atol=1e-13 * np.abs(fast).max())


@pytest.mark.parametrize("layout", ["C", "F"])
@pytest.mark.parametrize("fallback", [False, True])
def test_solve_spd_matches_numpy_for_both_layouts_and_both_lapack_paths(layout, fallback, monkeypatch):
    if fallback:
        monkeypatch.setattr(column_solve, "_DPOSV", None)
    rng = np.random.default_rng(3)
    X = rng.standard_normal((40, 40))
    H = X @ X.T + 0.1 * np.eye(40)
    for b in (rng.standard_normal(40), rng.standard_normal((40, 3))):
        x = column_solve.solve_spd(np.array(H, order=layout), b)
        assert x.shape == b.shape
        assert relative_error(x, np.linalg.solve(H, b)) < 1e-10
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
        column_solve.solve_spd(np.array(-H, order=layout), b)


def test_solve_spd_leaves_the_interpreter_to_other_threads():
    """NO17's solve runs in a background thread of the API (the landmark prior): while it factorises, the
    threads answering requests must still run Python. A call that held the GIL would stop this loop for the
    whole factorisation; here its longest pause must stay a small part of it."""
    assert column_solve._DPOSV is not None, "this SciPy exports no GIL-free dposv: the prior would stall the API"
    rng = np.random.default_rng(4)
    X = rng.standard_normal((2000, 2000))
    H = X @ X.T + np.eye(2000)
    done = threading.Event()
    took = []

    def solve():
        started = time.perf_counter()
        column_solve.solve_spd(H, np.ones(2000))
        took.append(time.perf_counter() - started)
        done.set()

    worker = threading.Thread(target=solve)
    longest, last = 0.0, time.perf_counter()
    worker.start()
    while not done.is_set():
        now = time.perf_counter()
        longest, last = max(longest, now - last), now
    worker.join()
    assert longest < 0.2 * took[0]  # holding the GIL (the f2py wrapper) gave 0.4-0.5


def test_bad_input_is_rejected():
    k = 5
    G, B, lam = np.eye(k), np.ones((k, k)), np.linspace(0, 1, k)
    with pytest.raises(CurvefmError, match="expected G"):
        solve_columns(G, B[:, :4], lam, lam, 1.0)
    with pytest.raises(CurvefmError, match="alpha"):
        solve_columns(G, B, lam, lam, -1.0)
    with pytest.raises(CurvefmError, match="finite"):
        solve_columns(G, np.full((k, k), np.nan), lam, lam, 1.0)
    with pytest.raises(InternalError, match="positive definite"):  # the solver never builds such a G
        solve_columns(-np.eye(k), B, lam, lam, 0.0)


@pytest.mark.slow
def test_faust_curves_match_reference(shared_data):
    """The acceptance inputs: one and five geodesic curves between FAUST tr_reg_000 and tr_reg_011."""
    from curvefm.fmap import restrict
    from curvefm.geometry import load_mesh, shortest_path
    from curvefm.registry import get

    k = 120
    plugin = get("basis", "laplace-beltrami")
    meshes = [load_mesh(shared_data / "faust" / f"tr_reg_0{i}.off") for i in ("00", "11")]
    bases = [plugin.run(mesh, k, plugin.parse_params({})) for mesh in meshes]
    (M, N), (basis_M, basis_N) = meshes, bases
    scale = max(basis_M.evals[-1], basis_N.evals[-1])
    lam_M, lam_N = basis_M.evals / scale, basis_N.evals / scale
    rng = np.random.default_rng(0)
    sums = np.zeros((3, k, k))  # G_M, G_N, B summed over the curves so far
    for n_curves in range(1, 6):
        a, b = rng.choice(M.n_vertices, 2, replace=False)
        path = shortest_path(M.edge_graph, a, b)  # FAUST meshes share vertex ids: the same path on N
        phi, psi = restrict(M.vertices, path, basis_M.evecs, 100), restrict(N.vertices, path, basis_N.evecs, 100)
        sums += np.stack([phi.T @ phi, psi.T @ psi, psi.T @ phi]) / 100
        if n_curves not in (1, 5):
            continue
        G_M, G_N, B = sums / n_curves
        for alpha in (0.01, 1.0, 100.0):
            C_MN, C_NM = solve_both(G_N, G_M, B, lam_N, lam_M, alpha)
            assert relative_error(C_MN, reference(G_N, B, lam_N, lam_M, alpha)) < 1e-8
            assert relative_error(C_NM, reference(G_M, B.T, lam_M, lam_N, alpha)) < 1e-8
