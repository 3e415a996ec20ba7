"""The curve-constrained solver: exactness, incremental updates, normalisation invariances."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from support.shapes import basis_of, ellipsoid, stretched_ellipsoid_pair

from curvefm.errors import Conflict, CurvefmError, NotFound
from curvefm.fmap import CurveMapSolver, conjugate_gradient_solve, quasi_newton_solve
from curvefm.geometry import shortest_path

K = 30


@pytest.fixture(scope="module")
def pair():
    return stretched_ellipsoid_pair()  # same connectivity: vertex i <-> vertex i


def curves_on(mesh, pairs):
    return [shortest_path(mesh.edge_graph, a, b) for a, b in pairs]


ENDPOINTS = [(0, 600), (100, 900), (250, 1100), (1152, 1153), (40, 700)]


def solver_with(pair, n_curves=3, **kwargs):
    M, bM, N, bN = pair
    solver = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K, **kwargs)
    paths = curves_on(M, ENDPOINTS[:n_curves])
    ids = solver.add_curves([(p, p, 1.0) for p in paths])
    return solver, ids, paths


def dense_k2_solve(G, B, lam_rows, lam_cols, alpha):
    """The map minimising the energy from its dense k^2 x k^2 normal equations, columns of C stacked:
    ``(I (x) G + alpha diag(vec D)) vec C = vec B``."""
    k, n = B.shape
    D = (lam_rows[:, None] - lam_cols[None, :]) ** 2
    H = np.kron(np.eye(n), G) + alpha * np.diag(D.T.ravel())
    return np.linalg.solve(H, B.T.ravel()).reshape(n, k).T


def test_solution_is_the_minimiser_of_the_full_k2_system(pair):
    solver, _, _ = solver_with(pair, alpha=10.0)
    G_M, G_N, B = solver.normal_equations()
    dense = dense_k2_solve(G_N, B, solver.lam_N, solver.lam_M, solver.alpha)
    np.testing.assert_allclose(solver.C_MN, dense, atol=1e-8 * np.abs(dense).max())
    # and it is a minimum: the energy rises in random directions
    E0 = solver.energy(solver.C_MN)
    rng = np.random.default_rng(0)
    assert all(solver.energy(solver.C_MN + 1e-3 * rng.standard_normal((K, K))) > E0 for _ in range(5))


def test_an_update_gives_both_maps_of_the_dense_k2_system(pair):
    """After an edit's update (a curve added, another removed) both maps are those of the dense solve."""
    M, *_ = pair
    solver, ids, _ = solver_with(pair, alpha=10.0)
    added = curves_on(M, [ENDPOINTS[4]])[0]
    solver.add_curve(added, added, weight=2.0)
    solver.remove_curve(ids[0])
    G_M, G_N, B = solver.normal_equations()
    for C, wanted in (
        (solver.C_MN, dense_k2_solve(G_N, B, solver.lam_N, solver.lam_M, solver.alpha)),
        (solver.C_NM, dense_k2_solve(G_M, B.T, solver.lam_M, solver.lam_N, solver.alpha)),
    ):
        np.testing.assert_allclose(C, wanted, atol=1e-8 * np.abs(wanted).max())


def test_paper_conjugate_gradients_reach_the_same_minimiser(pair):
    solver, _, _ = solver_with(pair, alpha=10.0)
    G_M, G_N, B = solver.normal_equations()
    C_cg, iterations = conjugate_gradient_solve(G_N, B, solver.lam_N, solver.lam_M, solver.alpha, tol=1e-12)
    assert iterations > 0
    np.testing.assert_allclose(C_cg, solver.C_MN, atol=1e-7 * np.abs(solver.C_MN).max())
    warm, warm_iterations = conjugate_gradient_solve(
        G_N, B, solver.lam_N, solver.lam_M, solver.alpha, C0=solver.C_MN, tol=1e-8
    )
    assert warm_iterations < iterations


def test_quasi_newton_reaches_the_same_minimiser(pair):
    solver, _, _ = solver_with(pair, alpha=10.0)
    G_M, G_N, B = solver.normal_equations()
    C_qn, iterations = quasi_newton_solve(G_N, B, solver.lam_N, solver.lam_M, solver.alpha, tol=1e-10)
    assert iterations > 0
    np.testing.assert_allclose(C_qn, solver.C_MN, atol=1e-5 * np.abs(solver.C_MN).max())
    assert solver.energy(C_qn) == pytest.approx(solver.energy(solver.C_MN), rel=1e-8, abs=1e-12)


def test_both_directions_are_solved(pair):
    M, bM, N, bN = pair
    solver, _, paths = solver_with(pair)
    reverse = CurveMapSolver(N.vertices, bN, M.vertices, bM, k=K)
    reverse.add_curves([(p, p, 1.0) for p in paths])
    np.testing.assert_allclose(solver.C_NM, reverse.C_MN, atol=1e-10)


def test_incremental_edits_equal_a_fresh_solve(pair):
    M, bM, N, bN = pair
    solver, ids, paths = solver_with(pair, n_curves=4)
    solver.remove_curve(ids[1])
    new_path = curves_on(M, [ENDPOINTS[4]])[0]
    solver.replace_curve(ids[2], new_path, new_path, weight=2.0)
    fresh = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K)
    fresh.add_curves([(paths[0], paths[0], 1.0), (new_path, new_path, 2.0), (paths[3], paths[3], 1.0)])
    np.testing.assert_allclose(solver.C_MN, fresh.C_MN, atol=1e-10)
    np.testing.assert_allclose(solver.C_NM, fresh.C_NM, atol=1e-10)


def test_interactive_solver_solves_each_map_on_first_read_and_gives_the_same_maps(pair):
    eager, _, paths = solver_with(pair, n_curves=2)
    lazy, ids, _ = solver_with(pair, n_curves=2, interactive=True)
    assert lazy.pending == {"MN", "NM"} and not eager.pending  # the interactive edits solved nothing yet
    np.testing.assert_allclose(lazy.C_MN, eager.C_MN, atol=1e-12)
    assert lazy.pending == {"NM"} and lazy.last_solve_ms > 0
    np.testing.assert_allclose(lazy.C_NM, eager.C_NM, atol=1e-12)
    assert not lazy.pending
    for solver in (eager, lazy):  # an edit after a read makes both maps stale again
        solver.add_curve(paths[0][::-1], paths[0][::-1], weight=3.0)
    assert lazy.pending == {"MN", "NM"}
    np.testing.assert_allclose(lazy.C_NM, eager.C_NM, atol=1e-12)
    np.testing.assert_allclose(lazy.C_MN, eager.C_MN, atol=1e-12)
    lazy.remove_curve(ids[0])
    eager.remove_curve("c1")
    np.testing.assert_allclose(lazy.C_NM, eager.C_NM, atol=1e-12)
    for curve_id in list(lazy.curves):
        lazy.remove_curve(curve_id)
    assert not lazy.pending and not lazy.C_MN.any()  # no curves: zero maps, nothing to solve


def test_invariant_to_the_number_of_curves_and_weights(pair):
    M, bM, N, bN = pair
    solver, _, paths = solver_with(pair)
    doubled = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K)
    doubled.add_curves([(p, p, 1.0) for p in paths + paths])
    np.testing.assert_allclose(doubled.C_MN, solver.C_MN, atol=1e-10)
    heavier = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K)
    heavier.add_curves([(paths[0], paths[0], 2.0)] + [(p, p, 1.0) for p in paths[1:]])
    extra = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K)
    extra.add_curves([(p, p, 1.0) for p in [paths[0]] + paths])
    np.testing.assert_allclose(heavier.C_MN, extra.C_MN, atol=1e-10)


def test_invariant_to_samples_per_curve(pair):
    coarse, _, _ = solver_with(pair, samples=200)
    fine, _, _ = solver_with(pair, samples=2000)
    assert np.linalg.norm(coarse.C_MN - fine.C_MN) < 0.02 * np.linalg.norm(fine.C_MN)


def test_invariant_to_mesh_scale(pair):
    M, bM, N, bN = pair
    big = ellipsoid(radii=(1.1, 0.6, 0.55), scale=250.0)
    solver, _, paths = solver_with(pair)
    scaled = CurveMapSolver(M.vertices, bM, big.vertices, basis_of(big), k=K)
    scaled.add_curves([(p, p, 1.0) for p in paths])
    signs = np.sign(np.sum(basis_of(big).evecs * bN.evecs, axis=0))[:K]  # eigenvectors are defined up to sign
    np.testing.assert_allclose(scaled.C_MN * signs[:, None], solver.C_MN, atol=1e-6 * np.abs(solver.C_MN).max())


def test_a_map_from_identical_curves_is_near_identity_on_the_same_shape(pair):
    M, bM, _, _ = pair
    solver = CurveMapSolver(M.vertices, bM, M.vertices, bM, k=K)
    solver.add_curves([(p, p, 1.0) for p in curves_on(M, ENDPOINTS)])
    assert np.linalg.norm(solver.C_MN - np.eye(K)) < 0.2 * np.sqrt(K)


def test_no_curves_means_no_map_and_bad_edits_are_rejected(pair):
    M, bM, N, bN = pair
    solver = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K)
    assert not solver.C_MN.any()
    with pytest.raises(NotFound, match="no curve 'c9'"):
        solver.remove_curve("c9")
    path = curves_on(M, [ENDPOINTS[0]])[0]
    with pytest.raises(CurvefmError, match="weight must be a positive"):
        solver.add_curve(path, path, weight=-1)
    with pytest.raises(CurvefmError, match="exceeds the computed bases"):
        CurveMapSolver(M.vertices, bM, N.vertices, bN, k=500)


def test_explicit_and_automatic_ids_coexist(pair):
    M, bM, N, bN = pair
    paths = curves_on(M, ENDPOINTS)
    with CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K) as solver:
        assert solver.add_curves([(p, p, 1.0) for p in paths[:2]], ids=["c1", "c3"]) == ["c1", "c3"]
        assert solver.add_curves([(p, p, 1.0) for p in paths[2:4]]) == ["c2", "c4"]  # automatic ids skip c1, c3
        assert solver.add_curve(paths[4], paths[4], curve_id="left arm") == "left arm"
        with pytest.raises(Conflict, match="'c3' already exists"):
            solver.add_curves([(paths[0], paths[0], 1.0), (paths[1], paths[1], 1.0)], ids=[None, "c3"])
        assert len(solver.curves) == 5  # nothing was added
        solver.remove_curve("c3")
        assert solver.add_curve(paths[1], paths[1], weight=2.0) == "c5"  # a removed id is not handed out again
        assert solver.add_curve(paths[1], paths[1], curve_id="c3") == "c3"  # but may be given explicitly
        solver.remove_curve("c1")
        order = ["c3", "c2", "c4", "left arm", "c5"]
        assert sorted(solver.curves) == sorted(order)
        fresh = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K)
        fresh.add_curves([(paths[i], paths[i], w) for i, w in ((1, 1.0), (2, 1.0), (3, 1.0), (4, 1.0), (1, 2.0))])
        np.testing.assert_allclose(solver.C_MN, fresh.C_MN, atol=1e-10)
        np.testing.assert_allclose(solver.C_NM, fresh.C_NM, atol=1e-10)


def test_a_solver_owns_its_thread_or_uses_the_one_it_is_handed(pair):
    M, bM, N, bN = pair
    paths = curves_on(M, ENDPOINTS[:2])
    reference = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K)
    reference.add_curves([(p, p, 1.0) for p in paths])
    with ThreadPoolExecutor(1) as executor:
        handed = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K, executor=executor)
        handed.add_curves([(p, p, 1.0) for p in paths])
        handed.close()  # leaves the executor to its owner
        assert executor.submit(lambda: 1).result() == 1
    np.testing.assert_allclose(handed.C_NM, reference.C_NM, atol=1e-12)
    reference.close()
    reference.add_curve(paths[0], paths[0])  # a closed solver starts a thread again when it needs one
    reference.close()


def test_many_random_edits_equal_a_fresh_solve(pair):
    """The solver keeps running sums of the curves' products; 200 random edits leave no visible rounding."""
    M, bM, N, bN = pair
    rng = np.random.default_rng(7)
    paths = curves_on(M, [tuple(rng.integers(0, M.n_vertices, 2)) for _ in range(12)])
    solver = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K, interactive=True)
    held: dict[str, tuple] = {}
    for _ in range(200):
        choice = rng.integers(len(paths))
        curve = (paths[choice], paths[(choice + 1) % len(paths)], float(rng.choice([0.5, 1.0, 30.0])))
        if held and rng.random() < 0.3:
            gone = str(rng.choice(sorted(held)))
            solver.remove_curve(gone)
            del held[gone]
        elif held and rng.random() < 0.5:
            changed = str(rng.choice(sorted(held)))
            solver.replace_curve(changed, *curve)
            held[changed] = curve
        else:
            held[solver.add_curve(*curve)] = curve
    fresh = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K)
    fresh.add_curves(list(held.values()), ids=list(held))
    scale = np.abs(fresh.C_MN).max()
    np.testing.assert_allclose(solver.C_MN, fresh.C_MN, atol=1e-9 * scale)
    np.testing.assert_allclose(solver.C_NM, fresh.C_NM, atol=1e-9 * np.abs(fresh.C_NM).max())


def test_sync_holds_exactly_the_given_curves(pair):
    M, bM, N, bN = pair
    solver, ids, paths = solver_with(pair, n_curves=3)
    new_path = curves_on(M, [ENDPOINTS[4]])[0]
    wanted = {ids[0]: (paths[0], paths[0], 1.0), ids[2]: (new_path, new_path, 2.0), "x": (paths[1], paths[1], 1.0)}
    solver.sync(wanted)
    assert list(solver.curves) == [ids[0], ids[2], "x"]
    fresh = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K)
    fresh.add_curves(list(wanted.values()), ids=list(wanted))
    np.testing.assert_allclose(solver.C_MN, fresh.C_MN, atol=1e-10)
    np.testing.assert_allclose(solver.C_NM, fresh.C_NM, atol=1e-10)
    solver.sync({})
    assert not solver.curves and not solver.C_MN.any()


def test_a_stored_curve_costs_its_paths_not_k_by_k_matrices(pair):
    import tracemalloc

    M, bM, N, bN = pair
    solver = CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K)
    paths = curves_on(M, ENDPOINTS)
    solver.add_curve(paths[0], paths[0])  # the solver's own k x k arrays exist from here on
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    for i in range(40):
        solver.add_curve(paths[i % len(paths)], paths[i % len(paths)])
    per_curve = (tracemalloc.get_traced_memory()[0] - before) / 40
    tracemalloc.stop()
    path_bytes = 2 * 4 * np.mean([len(p) for p in paths])
    assert per_curve < path_bytes + 2000 < 3 * K * K * 8, (per_curve, path_bytes)


def test_a_heavy_curve_removed_again_leaves_no_rounding_and_a_failed_solve_changes_nothing(pair):
    M, bM, N, bN = pair
    solver, _, paths = solver_with(pair, n_curves=2)
    before = solver.C_MN.copy()
    for weight in (1e12, 1e300):
        heavy = solver.add_curve(paths[0][::-1], paths[1], weight=weight)
        solver.remove_curve(heavy)
        np.testing.assert_allclose(solver.C_MN, before, atol=1e-10 * np.abs(before).max())
    with np.errstate(over="ignore"), pytest.raises(CurvefmError, match="finite"):
        solver.add_curve(paths[0], paths[1], weight=1e308)  # the sums overflow: the solve refuses them
    assert list(solver.curves) == ["c1", "c2"]
    np.testing.assert_array_equal(solver.C_MN, before)
    solver.add_curve(paths[0], paths[1])  # and the solver still works
    assert not np.allclose(solver.C_MN, before)


def test_restriction_samples_functions_by_the_sparse_operator(pair):
    """``restrict`` (row gathers) is ``P_gamma @ evecs`` with the barycentric operator, and samples a linear
    function of the coordinates exactly: its first and last samples are the path's endpoints."""
    from curvefm.fmap import restrict, restriction_operator
    from curvefm.fmap.restriction import resample

    M, bM, _, _ = pair
    path = curves_on(M, ENDPOINTS[:1])[0]
    operator = restriction_operator(M.n_vertices, *resample(M.vertices, path, 50))
    np.testing.assert_allclose(restrict(M.vertices, path, bM.evecs, 50), operator @ bM.evecs, atol=1e-12)
    positions = restrict(M.vertices, path, M.vertices, 50)
    np.testing.assert_allclose(positions[[0, -1]], M.vertices[[path[0], path[-1]]], atol=1e-12)


@pytest.mark.parametrize("energy", ["curves", "combined"])
def test_every_solver_on_the_same_source_reuses_its_curve_factors(monkeypatch, energy):
    """A collection's members share the template as their source: the template side of a curve is restricted
    once (SOURCE_FACTORS), and the maps are the same bit for bit as when every solver restricts it itself."""
    from curvefm.fmap import CombinedMapSolver, solver

    M, basis_M = ellipsoid(), basis_of(ellipsoid(), 20)
    members = [ellipsoid(radii=radii) for radii in ((1.1, 0.6, 0.55), (0.9, 0.8, 0.5))]
    make = {"curves": CurveMapSolver, "combined": CombinedMapSolver}[energy]
    curves = [(path, path, 1.0) for path in curves_on(M, ENDPOINTS[:2])]

    def maps_of(member):
        with make(M.vertices, basis_M, member.vertices, basis_of(member, 20), k=20) as one:
            one.add_curves(curves)
            return one.C_MN, one.C_NM

    restrictions = []
    original = solver.restrict
    monkeypatch.setattr(solver, "restrict", lambda *args: restrictions.append(args[0] is M.vertices) or original(*args))
    solver.SOURCE_FACTORS.clear()
    cold = [maps_of(member) for member in members]
    assert restrictions.count(True) == len(curves)  # the template side once per curve, not once per member
    assert restrictions.count(False) == len(curves) * len(members)

    solver.SOURCE_FACTORS.clear()
    uncached = maps_of(members[1])
    for got, expected in zip(uncached, cold[1], strict=True):
        assert np.array_equal(got, expected)
