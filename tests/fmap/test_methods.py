"""Map methods and descriptors: the OBCS12 / NO17 baselines, wave kernels, curves from ground truth."""

import numpy as np
import pytest
from support.ci import unavailable
from support.shapes import basis_of, stretched_ellipsoid_pair

from curvefm import registry
from curvefm.errors import CurvefmError
from curvefm.evaluation import CurvePool, evaluate_map, evaluate_pair, ground_truth_curves, ground_truth_for
from curvefm.evaluation.protocol import held_out_landmarks
from curvefm.evaluation.reproduce.datasets import Pair
from curvefm.evaluation.reproduce.scoring import LoadedPair
from curvefm.fmap import Hints, balanced_weights, descriptor_least_squares
from curvefm.fmap.baselines import DescriptorEnergy, effective_count, lbfgs
from curvefm.fmap.maps import curve_endpoints
from curvefm.geometry import build_mesh, check_edge_path, load_mesh, shortest_path
from curvefm.matching import pair_with_basis_size
from curvefm.pointwise import pointwise_from_fmap
from curvefm.progress import no_progress
from curvefm.spectral import (
    ShapePair,
    curve_function,
    multiplication_operators,
    scan_quadrature,
    wave_kernel_maps,
    wave_kernel_signature,
)
from curvefm.store import Store


@pytest.fixture(scope="module")
def pair():
    return stretched_ellipsoid_pair()  # same connectivity: vertex i <-> vertex i


@pytest.fixture(scope="module")
def shapes(pair) -> ShapePair:
    M, bM, N, bN = pair
    return ShapePair(M, N, bM, bN)


@pytest.fixture(scope="module")
def hints(pair) -> Hints:
    M = pair[0]
    curves = [(p, p) for p in (shortest_path(M.edge_graph, a, b) for a, b in ((0, 600), (100, 900), (250, 1100)))]
    return Hints.from_curves(curves)


def random_problem(k_from=12, k_to=10, d=30, seed=0):
    rng = np.random.default_rng(seed)
    F_from, F_to = rng.standard_normal((k_from, d)), rng.standard_normal((k_to, d))
    return F_from, F_to, np.sort(rng.random(k_from)), np.sort(rng.random(k_to))


def test_descriptor_least_squares_is_the_dense_least_squares_solution():
    F_from, F_to, lam_from, lam_to = random_problem()
    mu, d = 0.3, F_from.shape[1]
    C = descriptor_least_squares(F_from, F_to, lam_from, lam_to, mu)
    # vec(C F) = (F^T (x) I) vec(C) (columns stacked); commutativity: sqrt(mu) |lam_to_i - lam_from_j| C_ij
    A_descr = np.kron(F_from.T, np.eye(len(lam_to))) / np.sqrt(d)
    A_comm = np.diag(np.sqrt(mu) * np.abs(np.subtract.outer(lam_to, lam_from)).T.ravel())
    dense = np.linalg.lstsq(np.vstack([A_descr, A_comm]), np.r_[F_to.T.ravel() / np.sqrt(d), np.zeros(C.size)])[0]
    np.testing.assert_allclose(C, dense.reshape(C.shape, order="F"), atol=1e-9)


def test_descriptor_energy_gradient_matches_finite_differences():
    F_from, F_to, lam_from, lam_to = random_problem()
    rng = np.random.default_rng(1)
    X = rng.standard_normal((4, 12, 12))
    Y = rng.standard_normal((4, 10, 10))
    energy = DescriptorEnergy(
        F_from, F_to, lam_from, lam_to, X + X.transpose(0, 2, 1), Y + Y.transpose(0, 2, 1), 0.2, 1.0, 0.5
    )
    x = rng.standard_normal(120)
    value, grad = energy(x)
    step = 1e-6
    for i in rng.choice(120, 10, replace=False):
        e = np.zeros(120)
        e[i] = step
        numeric = (energy(x + e)[0] - energy(x - e)[0]) / (2 * step)
        assert numeric == pytest.approx(grad[i], rel=1e-5, abs=1e-6)


def test_exact_minimiser_zeroes_the_gradient_and_agrees_with_lbfgs():
    F_from, F_to, lam_from, lam_to = random_problem(k_from=8, k_to=7)
    rng = np.random.default_rng(3)
    X, Y = rng.standard_normal((5, 8, 8)), rng.standard_normal((5, 7, 7))
    energy = DescriptorEnergy(
        F_from, F_to, lam_from, lam_to, X + X.transpose(0, 2, 1), Y + Y.transpose(0, 2, 1), 0.2, 1.0, 0.5
    )
    C = energy.minimiser()
    value, grad = energy(C.ravel())
    assert np.abs(grad).max() < 1e-8 * max(1.0, value)
    assert energy(C.ravel() + 1e-3 * rng.standard_normal(C.size))[0] > value  # a minimum, not a saddle
    np.testing.assert_allclose(lbfgs(energy, np.zeros_like(C), 5000)[0], C, atol=1e-5)


def test_balanced_weights_ignore_how_often_a_descriptor_is_repeated():
    F_from, F_to, lam_from, lam_to = random_problem(d=6)
    no_ops_from, no_ops_to = np.zeros((0, 12, 12)), np.zeros((0, 10, 10))
    once = balanced_weights(F_from, F_to, lam_from, lam_to, no_ops_from, no_ops_to, 0.5, 0.0)
    thrice = balanced_weights(np.tile(F_from, 3), np.tile(F_to, 3), lam_from, lam_to, no_ops_from, no_ops_to, 0.5, 0.0)
    # DescriptorEnergy divides by d, so the weight per descriptor column is w_descr / d: the same total
    assert effective_count(np.tile(F_from, 3)) == pytest.approx(effective_count(F_from))
    assert thrice[0] / 18 * 3 == pytest.approx(once[0] / 6)
    assert thrice[1] == pytest.approx(once[1])


def test_lbfgs_without_commutativity_reaches_the_least_squares_map():
    F_from, F_to, lam_from, lam_to = random_problem()
    empty_from, empty_to = np.zeros((0, 12, 12)), np.zeros((0, 10, 10))
    energy = DescriptorEnergy(F_from, F_to, lam_from, lam_to, empty_from, empty_to, 0.3, 1.0, 0.0)
    C, iterations = lbfgs(energy, np.zeros((10, 12)), 5000)
    assert iterations > 0
    np.testing.assert_allclose(C, descriptor_least_squares(F_from, F_to, lam_from, lam_to, 0.3), atol=1e-6)


def test_wave_kernels_are_intrinsic_and_symmetric(pair):
    M, bM, _, _ = pair
    moved = build_mesh(3.0 * M.vertices @ np.linalg.qr(np.random.default_rng(2).standard_normal((3, 3)))[0], M.faces)
    wks, wks_moved = wave_kernel_signature(bM), wave_kernel_signature(basis_of(moved))
    assert wks.shape == (M.n_vertices, 20)
    np.testing.assert_allclose(wks_moved, wks, atol=1e-6 * np.abs(wks).max())  # scale and rotation invariant
    wkm = wave_kernel_maps(bM, [5, 700], n_energies=8).reshape(M.n_vertices, 2, 8)
    np.testing.assert_allclose(wkm[700, 0], wkm[5, 1], atol=1e-12)  # k_e(p, q) = k_e(q, p)


def test_curve_function_and_multiplication_operators(pair):
    M, bM, _, _ = pair
    path = shortest_path(M.edge_graph, 0, 600)
    f = curve_function(M.vertices, path)
    assert f[path[0]] == 0 and f[path[-1]] == 1 and np.all(np.diff(f[path]) > 0)
    assert np.all(f[np.setdiff1d(np.arange(M.n_vertices), path)] == -1)
    ops = multiplication_operators(bM, np.c_[np.ones(M.n_vertices), f], 10)
    np.testing.assert_allclose(ops[0], np.eye(10), atol=1e-10)  # multiplying by 1 is the identity
    np.testing.assert_allclose(ops[1], ops[1].T, atol=1e-12)
    with pytest.raises(CurvefmError, match="zero length"):
        curve_function(M.vertices, np.array([3, 3]))


def test_scan_quadrature_integrates_the_operators_on_samples(pair, monkeypatch):
    M, bM, _, _ = pair
    assert scan_quadrature(M.vertices, bM.mass) is None  # below QUADRATURE_FROM_VERTICES: every vertex, as before
    monkeypatch.setattr("curvefm.spectral.descriptors.QUADRATURE_FROM_VERTICES", 0)
    quadrature = scan_quadrature(M.vertices, bM.mass, points=M.n_vertices // 3)
    assert quadrature is not None and len(quadrature.rows) == M.n_vertices // 3
    assert quadrature.weights.sum() == pytest.approx(1.0) and np.all(quadrature.weights > 0)
    functions = np.c_[np.ones(M.n_vertices), bM.evecs[:, 1:6]]
    full = multiplication_operators(bM, functions, 10)
    sampled = multiplication_operators(bM, functions, 10, quadrature)
    relative = np.linalg.norm(sampled - full, axis=(1, 2)) / np.linalg.norm(full, axis=(1, 2))
    assert relative.max() < 0.1 and not np.allclose(sampled, full)  # a third of the vertices, smooth products


@pytest.mark.parametrize(
    "name, params",
    [
        ("curves", {}),
        ("obcs12", {"k": 20, "spectrum": 40}),
        ("no17", {"k": 20, "spectrum": 40}),
        ("no17", {"k": 20, "spectrum": 40, "inputs": "curves"}),
    ],
)
def test_every_method_maps_a_shape_to_its_stretched_copy(shapes, hints, name, params):
    plugin, parsed = registry.load("method", name, params)
    maps = plugin.run(shapes, hints, parsed, no_progress)
    k = params.get("k", 40)
    assert maps.C_MN.shape == maps.C_NM.shape == (k, k)
    # same connectivity, vertex i <-> vertex i: the pointwise map must beat a random one by far
    N = shapes.mesh_N
    p2p_MN = pointwise_from_fmap(maps.C_NM, shapes.basis_N, shapes.basis_M)
    error = np.linalg.norm(N.vertices[p2p_MN] - N.vertices, axis=1).mean()
    shuffled = np.linalg.norm(N.vertices[np.random.default_rng(0).permutation(N.n_vertices)] - N.vertices, axis=1)
    assert error < 0.2 * shuffled.mean()  # measured: curves 0.015, NO17 0.02-0.07, OBCS12 0.12 of it


def test_methods_report_bad_input(shapes, hints):
    with pytest.raises(CurvefmError, match="unknown method 'magic'; installed methods: combined, curves, no17, obcs12"):
        registry.get("method", "magic")
    with pytest.raises(CurvefmError, match="bad parameters for 'no17': inputs"):
        registry.get("method", "no17").parse_params({"inputs": "pictures"})
    plugin = registry.get("method", "obcs12")
    with pytest.raises(CurvefmError, match="k = 300 but the bases have only 40"):
        plugin.run(shapes, hints, plugin.parse_params({"k": 300}), no_progress)
    with pytest.raises(CurvefmError, match="at least one landmark"):
        plugin.run(shapes, Hints(), plugin.parse_params({"k": 20, "spectrum": 40}), no_progress)
    alone = plugin.parse_params({"k": 20, "spectrum": 40, "landmarks": False})
    descriptors_alone = plugin.run(shapes, Hints(), alone, no_progress)
    assert descriptors_alone.C_MN.shape == (20, 20)  # wave kernel signatures need no landmarks


def test_curve_endpoints_are_distinct_landmark_pairs():
    curves = [(np.array([1, 2, 3]), np.array([7, 8])), (np.array([3, 4]), np.array([8, 9]))]
    assert curve_endpoints(curves).tolist() == [[1, 7], [3, 8], [4, 9]]


def test_curve_pool_draws_seeded_traced_and_exact_curves(shared_data):
    source, target = shared_data / "faust_5k_bcicp/tr_reg_000.off", shared_data / "faust_5k_bcicp/tr_reg_011.off"
    M, N = load_mesh(source), load_mesh(target)
    truth = ground_truth_for(source, target, M, N)
    pool = CurvePool(M, N, truth, size=20)
    assert pool.endpoints(5, seed=3) == pool.endpoints(5, seed=3) != pool.endpoints(5, seed=4)
    assert len(set(pool.endpoints(30, seed=0))) == 30
    partner = dict(zip(truth.ids_X.tolist(), truth.ids_Y.tolist(), strict=True))
    for exact in (False, True):
        for path_M, path_N in pool.curves(4, seed=0, exact=exact):
            check_edge_path(M.edge_graph, path_M)
            check_edge_path(N.edge_graph, path_N)  # remeshed target: carried paths are closed into edge paths
            assert (path_N[0], path_N[-1]) == (partner[int(path_M[0])], partner[int(path_M[-1])])
    with pytest.raises(CurvefmError, match="cannot give 1000 distinct curves"):
        pool.endpoints(1000, seed=0)


def test_exact_curves_need_dense_ground_truth(shared_data):
    source, target = shared_data / "tosca/horse0.off", shared_data / "tosca/wolf0.off"
    M, N = load_mesh(source), load_mesh(target)
    pool = CurvePool(M, N, ground_truth_for(source, target, M, N))
    assert len(pool.landmarks) == 21  # the shared animal landmarks
    with pytest.raises(CurvefmError, match="exact curves need a dense ground truth"):
        pool.curves(2, seed=0, exact=True)


def test_sparse_truth_holds_landmarks_out_of_the_curves(shared_data):
    """With 21 landmarks, 20 curves drawn from all of them would end at nearly every point the maps are scored at."""
    source, target = shared_data / "tosca/horse0.off", shared_data / "tosca/wolf0.off"
    M, N = load_mesh(source), load_mesh(target)
    pool = CurvePool(M, N, ground_truth_for(source, target, M, N))
    assert pool.max_curves == 14 * 13 // 2
    held_out = [set(pool.held_out(seed).tolist()) for seed in range(3)]
    assert all(len(h) == 7 for h in held_out) and set.union(*held_out) == set(pool.landmarks.tolist())
    for seed in range(3):
        ends = {v for pair in pool.endpoints(20, seed) for v in pair}
        assert ends <= set(pool.landmarks.tolist()) and not ends & held_out[seed]
        assert len(ends) > 7  # the curves still spread over the remaining landmarks


def test_evaluate_scores_a_sparse_truth_at_landmarks_the_curves_avoid(shared_data, tmp_path):
    source, target = shared_data / "tosca/horse0.off", shared_data / "tosca/wolf0.off"
    report = evaluate_pair(source, target, n_curves=3, k=20, store=Store(tmp_path))
    assert report["scored_at"] == "7 landmarks the curves were not drawn from, none at a curve's end"
    assert report["errors"]["source_to_target"]["count"] == report["errors"]["target_to_source"]["count"] == 7
    M, N = load_mesh(source), load_mesh(target)
    truth = ground_truth_for(source, target, M, N)
    ends = {int(v) for path_M, _ in ground_truth_curves(M, N, truth, 3) for v in (path_M[0], path_M[-1])}
    assert len(ends) == 6 and not ends & set(held_out_landmarks(truth, 0).tolist())
    with pytest.raises(CurvefmError, match="14 known correspondences .the others are held out"):
        ground_truth_curves(M, N, truth, 8)


def test_maps_are_scored_at_the_held_out_landmarks_only(shared_data, tmp_path):
    pair = Pair("tosca-cross", "tosca/horse0.off", "tosca/wolf0.off")
    loaded = LoadedPair.load(shared_data, pair, 20, Store(tmp_path))
    C_NM = np.eye(20)
    scorer = loaded.scorers["source"]
    everywhere = scorer(C_NM, loaded.shapes.basis_M, loaded.shapes.basis_N, np.ones(len(scorer.rows_from), bool))
    assert everywhere.count == 21
    for seed in range(2):
        held_out = loaded.pool.held_out(seed)
        mask = np.isin(scorer.rows_from, held_out)
        scored = loaded.score(C_NM, seed, curves=[])
        assert scored.count == 7 == mask.sum()
        p2p = np.zeros(loaded.shapes.mesh_M.n_vertices, dtype=np.int64)
        p2p[held_out] = pointwise_from_fmap(C_NM, loaded.shapes.basis_N, loaded.shapes.basis_M, rows=held_out)
        partner = dict(zip(loaded.truth.ids_X.tolist(), loaded.truth.ids_Y.tolist(), strict=True))
        truth = (held_out, np.array([partner[int(v)] for v in held_out]))
        assert scored.mean == pytest.approx(evaluate_map(p2p, truth, loaded.shapes.mesh_N).mean, rel=1e-5)


@pytest.mark.slow
@pytest.mark.parametrize(
    "pair_files", [("nonisometric/pyfm_cat_lion/cat-00.off", "nonisometric/pyfm_cat_lion/lion-00.off")]
)  # noqa: E501
def test_no17_is_as_accurate_as_pyfm_given_the_same_landmarks(shared_data, tmp_path, pair_files):
    try:
        from pyFM.functional import FunctionalMapping
        from pyFM.mesh import TriMesh
    except ImportError:
        unavailable("pyFM (pip install -e '.[bench]') is needed to compare NO17 with it")
    source, target = (shared_data / p for p in pair_files)
    M, N = load_mesh(source), load_mesh(target)
    truth = ground_truth_for(source, target, M, N)
    hints = Hints.from_curves(ground_truth_curves(M, N, truth, 2))  # 4 landmarks: the curves' endpoints
    pair = pair_with_basis_size(Store(tmp_path), (M, N), 120)
    plugin, params = registry.load("method", "no17")
    ours = pointwise_from_fmap(plugin.run(pair, hints, params, no_progress).C_NM, pair.basis_N, pair.basis_M)
    model = FunctionalMapping(*(TriMesh(m.vertices, m.faces, area_normalize=True, center=True) for m in (N, M)))
    model.preprocess(n_descr=100, descr_type="WKS", landmarks=hints.landmarks[:, ::-1], k_process=120)
    model.fit(K=(50, 50))
    ours_error = evaluate_map(ours, truth, N).mean_area
    pyfm_error = evaluate_map(model.get_p2p(), truth, N).mean_area
    assert ours_error <= 1.05 * pyfm_error, (ours_error, pyfm_error)


def test_both_bases_are_computed_at_once_as_each_alone_with_one_progress(pair, tmp_path):
    M, _, N, _ = pair
    reports = []
    together = pair_with_basis_size(Store(tmp_path / "together"), (M, N), 30, progress=lambda f, m: reports.append(f))
    for mesh, basis in ((M, together.basis_M), (N, together.basis_N)):
        alone = Store(tmp_path / "alone").ensure_basis(mesh, 30)
        np.testing.assert_allclose(basis.evals, alone.evals, rtol=1e-10)
        np.testing.assert_allclose(np.abs(basis.evecs), np.abs(alone.evecs), atol=1e-8)
    assert reports and max(reports) == pytest.approx(1.0) and all(0.0 <= f <= 1.0 for f in reports)
    same = pair_with_basis_size(Store(tmp_path / "same"), (M, M), 30)
    assert same.basis_M is same.basis_N
    assert len(Store(tmp_path / "same").stored_bases(M.content_hash)) == 1
