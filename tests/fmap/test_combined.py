"""The combined energy (curves, wave kernel signatures, wave kernel maps along the curves): its solver against an
independent dense least-squares solve, incremental edits against a fresh solve, sessions that keep their energy,
and its accuracy on a real pair with ground truth."""

import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from support.shapes import basis_of, ellipsoid

from curvefm import registry
from curvefm.evaluation import ground_truth_curves, ground_truth_for, score
from curvefm.evaluation.ground_truth import GroundTruth
from curvefm.fmap import (
    DEFAULT_PRIOR_WEIGHT,
    CombinedMapSolver,
    CurveMapSolver,
    Hints,
    combined,
    landmark_prior,
    restrict,
)
from curvefm.fmap.combined import (
    ONE_CURVE_PRIOR_FACTOR,
    PRIOR_DELAY_S,
    full_size_length,
    kernel_coefficients,
    kernel_filters,
    signature_coefficients,
)
from curvefm.fmap.landmark_prior import NO17Settings, NoLongerWanted, descriptor_part, landmark_maps
from curvefm.geometry import load_mesh, shortest_path
from curvefm.matching import match
from curvefm.records.sessions import sessions_of
from curvefm.session import (
    CurveSpec,
    LiveSessions,
    SessionCreate,
    SessionEditor,
    SessionRecord,
    build_solver,
    load_pair,
)
from curvefm.spectral import normalised, wave_kernel_maps
from curvefm.store import Store

K = 12
ENDPOINTS = [(0, 600), (100, 900), (250, 1100), (40, 700)]
WEIGHTS = {"alpha": 3.0, "descriptor_weight": 5.0, "kernel_weight": 20.0}


@pytest.fixture(scope="module")
def shapes():
    M, N = ellipsoid(), ellipsoid(radii=(1.1, 0.6, 0.55))
    return M, basis_of(M, K), N, basis_of(N, K)


@pytest.fixture(scope="module")
def paths(shapes):
    M, _, N, _ = shapes
    return [(shortest_path(M.edge_graph, a, b), shortest_path(N.edge_graph, a, b)) for a, b in ENDPOINTS]


def solver_on(shapes, **params):
    M, bM, N, bN = shapes
    return CombinedMapSolver(M.vertices, bM, N.vertices, bN, k=K, **(WEIGHTS | params))


def dense_least_squares(shapes, curves, alpha, descriptor_weight, kernel_weight, samples=100, prior=None):
    """C_MN minimising the combined energy, from its terms written as one k^2-column least-squares system
    (``vec(A C B) = (B^T kron A) vec(C)``, columns stacked): no normal equations, no column solves.
    ``prior``: ``(C0, weight)`` adds ``weight ||C - C0||^2`` (C0 the whole map here)."""
    M, bM, N, bN = shapes
    scale = max(bM.evals[-1], bN.evals[-1])
    lam_M, lam_N = bM.evals / scale, bN.evals / scale
    eye = np.eye(K)
    blocks = [(np.sqrt(alpha) * (np.kron(np.diag(lam_M), eye) - np.kron(eye, np.diag(lam_N))), np.zeros(K * K))]

    def rows(F_N, F_M, weight):  # weight * ||F_N C - F_M||^2
        return np.sqrt(weight) * np.kron(eye, F_N), np.sqrt(weight) * F_M.ravel(order="F")

    S_M, S_N = signature_coefficients(bM), signature_coefficients(bN)
    blocks.append(rows(S_N.T, S_M.T, descriptor_weight / S_M.shape[1]))
    for path_M, path_N, weight in curves:
        share = weight / sum(c[2] for c in curves)
        phi = restrict(M.vertices, path_M, bM.evecs, samples)
        psi = restrict(N.vertices, path_N, bN.evecs, samples)
        blocks.append(rows(psi, phi, share / samples))
        K_M = kernel_coefficients(phi, kernel_filters(bM.evals))
        K_N = kernel_coefficients(psi, kernel_filters(bN.evals))
        blocks.append(rows(K_N.T, K_M.T, kernel_weight * share / K_M.shape[1]))
    if prior is not None:
        C0, weight = prior
        blocks.append((np.sqrt(weight) * np.eye(K * K), np.sqrt(weight) * C0.ravel(order="F")))
    A = np.vstack([a for a, _ in blocks])
    b = np.concatenate([b for _, b in blocks])
    return np.linalg.lstsq(A, b, rcond=None)[0].reshape(K, K, order="F")


def test_the_solver_minimises_the_combined_energy(shapes, paths):
    curves = [(pm, pn, w) for (pm, pn), w in zip(paths[:3], (1.0, 2.0, 0.5), strict=True)]
    with solver_on(shapes, prior_weight=0.0) as solver:
        solver.add_curves(curves)
        expected = dense_least_squares(shapes, curves, **WEIGHTS)
        assert np.allclose(solver.C_MN, expected, atol=1e-7 * np.abs(expected).max())
        assert solver.energy(solver.C_MN) < solver.energy(solver.C_MN + 1e-3 * np.eye(K))


def test_from_full_size_curves_on_the_map_is_solved_with_the_full_size_weights(shapes, paths):
    curves = [(pm, pn, 1.0) for pm, pn in paths]
    full_size = {"alpha": 0.5, "descriptor_weight": WEIGHTS["descriptor_weight"], "kernel_weight": 70.0}
    with solver_on(
        shapes, prior_weight=0.0, full_size_curves=4, full_size_alpha=0.5, full_size_kernel_weight=70.0
    ) as solver:
        ids = solver.add_curves(curves)
        assert solver.full_size and solver.commutativity_weight == 0.5
        expected = dense_least_squares(shapes, curves, **full_size)
        assert np.allclose(solver.C_MN, expected, atol=1e-7 * np.abs(expected).max())
        solver.remove_curve(ids[-1])  # below the count again: the weights the solver was made with
        assert not solver.full_size and solver.commutativity_weight == WEIGHTS["alpha"]
        expected = dense_least_squares(shapes, curves[:3], **WEIGHTS)
        assert np.allclose(solver.C_MN, expected, atol=1e-7 * np.abs(expected).max())


def test_with_the_source_area_the_curves_length_decides_the_whole_map(shapes, paths):
    # an area that puts full_size_length(K) between the first curve's length and the first two curves' total
    M = shapes[0]
    lengths = np.cumsum([np.linalg.norm(np.diff(M.vertices[p], axis=0), axis=1).sum() for p, _ in paths])
    area = ((lengths[0] + lengths[1]) / 2 / full_size_length(K)) ** 2
    with solver_on(shapes, prior_weight=0.0, full_size_alpha=0.5, source_area=area) as solver:
        for count, (path_M, path_N) in enumerate(paths, start=1):
            solver.add_curve(path_M, path_N)
            assert solver.curves_length == pytest.approx(lengths[count - 1] / np.sqrt(area))
            assert solver.full_size == (count >= 2) and solver.commutativity_weight == (0.5 if count >= 2 else 3.0)
        summary = solver.effective().summary
        assert summary.startswith(f"combined; {K} x {K} from curves totalling {full_size_length(K):.1f} sqrt(area)")


@pytest.mark.parametrize("count", [1, 2])
def test_the_landmark_prior_pulls_the_map_towards_no17_from_the_endpoints(shapes, paths, count):
    curves = [(pm, pn, 1.0) for pm, pn in paths[:count]]
    with solver_on(shapes, prior_weight=5.0) as solver:
        solver.add_curves(curves)
        prior = landmark_maps(solver.basis_M, solver.basis_N, Hints.from_curves(paths[:count]).landmarks)
        G_M, G_N, _ = solver.normal_equations()
        factor = ONE_CURVE_PRIOR_FACTOR if count == 1 else 1.0  # one curve misleads most: the prior counts more
        weight = 5.0 * factor * (np.trace(G_M) + np.trace(G_N)) / (2 * K)  # relative to the systems' mean diagonal
        expected = dense_least_squares(shapes, curves, **WEIGHTS, prior=(prior.C_MN, weight))
        assert np.allclose(solver.C_MN, expected, atol=1e-7 * np.abs(expected).max())
        without = dense_least_squares(shapes, curves, **WEIGHTS)
        assert np.linalg.norm(solver.C_MN - prior.C_MN) < 0.5 * np.linalg.norm(without - prior.C_MN)


def test_on_scans_the_prior_integrates_its_operators_on_samples(shapes, paths, monkeypatch):
    curves = [(pm, pn, 1.0) for pm, pn in paths[:3]]
    with solver_on(shapes, prior_weight=5.0) as solver:  # ellipsoids are below QUADRATURE_FROM_VERTICES
        solver.add_curves(curves)
        every_vertex = solver.C_MN
    monkeypatch.setattr("curvefm.spectral.descriptors.QUADRATURE_FROM_VERTICES", 0)
    monkeypatch.setattr("curvefm.spectral.descriptors.QUADRATURE_POINTS", shapes[0].n_vertices // 2)
    with solver_on(shapes, prior_weight=5.0) as solver:
        solver.add_curves(curves)
        sampled = solver.C_MN
    change = np.linalg.norm(sampled - every_vertex) / np.linalg.norm(every_vertex)
    # the same prior to within its operators' quadrature on half the vertices (not the cached full-sum parts)
    assert 0 < change < 0.05


def test_an_interactive_solver_computes_the_prior_in_the_background(shapes, paths):
    curves = [(pm, pn, 1.0) for pm, pn in paths[:2]]
    with ThreadPoolExecutor(1) as background, solver_on(shapes) as at_once:
        at_once.add_curves(curves)
        with solver_on(shapes, interactive=True, prior_executor=background) as live:
            live.add_curves(curves)
            assert live.prior_pending  # nothing read yet: no prior asked for
            first = live.C_MN.copy()  # solved without a prior; the prior's job starts
            assert not np.allclose(first, at_once.C_MN, atol=1e-6)
            live.settle()
            assert not live.prior_pending
            assert np.allclose(live.C_MN, at_once.C_MN, rtol=0, atol=1e-12)
            assert np.allclose(live.C_NM, at_once.C_NM, rtol=0, atol=1e-12)
            (gone,) = live.add_curves([(*paths[2], 1.0)])
            live.C_MN  # noqa: B018  (starts the job for the new endpoints)
            live.remove_curve(gone)
            assert not live.prior_pending  # back to the endpoints the prior was computed for
            assert np.allclose(live.C_MN, at_once.C_MN, rtol=0, atol=1e-12)


def test_an_edit_stops_a_running_prior_for_other_endpoints_before_the_maps_are_read(shapes, paths, monkeypatch):
    asked_for, gave_up = [], threading.Event()

    def prior_until_unwanted(basis_M, basis_N, landmarks, wanted, extra=None, quadratures=None):  # a long computation
        asked_for.append(len(landmarks))
        deadline = time.monotonic() + 30
        while wanted() and time.monotonic() < deadline:
            time.sleep(0.005)
        if not wanted():
            gave_up.set()
        raise NoLongerWanted

    monkeypatch.setattr(combined, "landmark_maps", prior_until_unwanted)
    with ThreadPoolExecutor(1) as background:
        with solver_on(shapes, interactive=True, prior_executor=background) as live:
            live.add_curves([(*paths[0], 1.0)])
            live.C_MN  # noqa: B018  (starts the job: it waits PRIOR_DELAY_S, then computes until unwanted)
            live.add_curves([(*paths[1], 1.0)])  # nothing read since
            assert gave_up.wait(PRIOR_DELAY_S + 10)
            assert asked_for == [2]  # the first curve's two endpoints; no job yet for the new ones


def test_after_a_prior_gives_up_for_an_edit_the_current_endpoints_prior_still_lands(shapes, paths, monkeypatch):
    """The job running when the edit came gives up; the maps read since were solved without a prior. The next
    read that finds it given up must start the current endpoints' job, or the prior would stay pending (and the
    page would poll for it) until the next edit."""
    real_prior, running = combined.landmark_maps, threading.Event()

    def prior_that_takes_a_while(basis_M, basis_N, landmarks, wanted=lambda: True, extra=None, quadratures=None):
        running.set()
        for _ in range(200):
            if not wanted():
                raise NoLongerWanted
            time.sleep(0.005)
        return real_prior(basis_M, basis_N, landmarks, extra=extra)

    monkeypatch.setattr(combined, "landmark_maps", prior_that_takes_a_while)
    monkeypatch.setattr(combined, "PRIOR_DELAY_S", 0.05)
    with ThreadPoolExecutor(1) as background, solver_on(shapes) as at_once:
        at_once.add_curves([(pm, pn, 1.0) for pm, pn in paths[:2]])
        with solver_on(shapes, interactive=True, prior_executor=background) as live:
            live.add_curves([(*paths[0], 1.0)])
            live.C_MN  # noqa: B018  (starts the first curve's job)
            assert running.wait(10)
            live.add_curves([(*paths[1], 1.0)])
            live.C_MN  # noqa: B018  (solved without a prior; the running job is for the old endpoints)
            deadline = time.monotonic() + 30
            while live.prior_pending and time.monotonic() < deadline:
                time.sleep(0.02)  # reads, as the page's polls do
            assert not live.prior_pending
            assert np.allclose(live.C_MN, at_once.C_MN, rtol=0, atol=1e-12)


def test_a_prior_no_longer_wanted_stops_at_its_next_step(shapes, paths):
    """The background prior gives up when newer endpoints are wanted: each descriptor part and each direction
    asks first, so a job stops after the step it was in, and its finished parts serve the next job."""
    _, bM, _, bN = shapes
    landmarks = Hints.from_curves(paths[:2]).landmarks
    asked = []

    def wanted_for(steps):
        return lambda: asked.append(1) or len(asked) <= steps

    with pytest.raises(NoLongerWanted):
        landmark_maps(bM, bN, landmarks, wanted=wanted_for(3))
    assert len(asked) == 4  # three steps, then the fourth asked and stopped
    asked.clear()
    maps = landmark_maps(bM, bN, landmarks, wanted=lambda: asked.append(1) or True)
    assert len(asked) == 2 * (1 + len(landmarks)) + 2  # a part per side for signatures and each landmark, 2 solves
    expected = landmark_maps(bM, bN, landmarks)
    assert np.array_equal(maps.C_MN, expected.C_MN) and np.array_equal(maps.C_NM, expected.C_NM)


@pytest.mark.parametrize(("k", "spectrum"), [(8, K), (K, K), (6, 10)])
def test_a_landmarks_part_from_the_eigenfunctions_operators_equals_the_part_of_its_kernel_maps(shapes, k, spectrum):
    """A landmark's part is made from the coefficients of its kernel maps and the eigenfunctions' operators; it
    must equal the part computed from the kernel maps as functions on the vertices (k below the spectrum, and a
    spectrum below the basis, too)."""
    _, bM, _, _ = shapes
    settings = NO17Settings(k=k, spectrum=spectrum, energies=6)
    for landmark in (3, 500, 1100):
        part = landmark_prior._part(bM, landmark, settings)
        kernel_maps = wave_kernel_maps(bM.truncated(spectrum), np.array([landmark]), **settings.filters())
        functions = normalised(bM, kernel_maps)
        expected = descriptor_part(bM, functions, k)
        assert part.operators.shape == (6, k, k) and part.coefficients.shape == (k, 6)
        for mine, theirs in ((part.coefficients, expected.coefficients), (part.operators, expected.operators)):
            assert np.abs(theirs).max() > 0
            np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-10 * np.abs(theirs).max())


def test_incremental_edits_equal_a_fresh_solve(shapes, paths):
    with solver_on(shapes) as edited, solver_on(shapes) as fresh:
        ids = edited.add_curves([(pm, pn, 1.0) for pm, pn in paths[:3]])
        edited.remove_curve(ids[1])
        edited.replace_curve(ids[0], *paths[3], weight=2.0)
        fresh.add_curves([(*paths[3], 2.0), (*paths[2], 1.0)])
        for mine, theirs in ((edited.C_MN, fresh.C_MN), (edited.C_NM, fresh.C_NM)):
            assert np.abs(mine).max() > 0
            assert np.allclose(mine, theirs, rtol=0, atol=1e-9 * np.abs(theirs).max())


def test_the_descriptor_terms_change_the_map(shapes, paths):
    M, bM, N, bN = shapes
    with solver_on(shapes) as combined, CurveMapSolver(M.vertices, bM, N.vertices, bN, k=K, alpha=3.0) as curves:
        for solver in (combined, curves):
            solver.add_curves([(pm, pn, 1.0) for pm, pn in paths[:2]])
        assert not np.allclose(combined.C_MN, curves.C_MN, atol=1e-3)


def test_signatures_are_computed_once_per_basis(shapes):
    _, bM, _, _ = shapes
    assert signature_coefficients(bM) is signature_coefficients(bM)


@pytest.fixture(scope="module")
def faust(shared_data, tmp_path_factory):
    source, target = shared_data / "faust/tr_reg_000.off", shared_data / "faust/tr_reg_011.off"
    M, N = load_mesh(source), load_mesh(target)
    return M, N, ground_truth_for(source, target, M, N), Store(tmp_path_factory.mktemp("store"))


def test_the_combined_default_beats_the_curve_energy_and_no17_from_the_same_endpoints(faust):
    # the protocol: 2n farthest points among ground-truth vertices, consecutive pairs joined,
    # nearest-neighbour conversion, mean geodesic error / sqrt(area). The energies are compared under plain nearest
    # neighbours, as maps of different sizes: the conversion's orthogonal steps fit a 50 x 50 map at 50 x 80 and a
    # 120 x 120 one from its 90 x 90 block at 90 x 120 (docs/decisions.md#orthogonal-steps-in-the-conversion)
    M, N, truth, store = faust
    errors = {}
    plain = {"orthogonal_steps": 0}
    for count in (2, 10):
        curves = ground_truth_curves(M, N, truth, count)
        for method in ("combined", "curves", "no17"):
            result = match(M, N, curves, store=store, method=method, converter_params=plain)
            errors[method, count] = score(result, truth)["source_to_target"]["mean_area"]
            if method == "combined":  # the prior's size until the curves total full_size_length(120) = 6.2
                size = 50 if count == 2 else 120  # FAUST's 10 farthest-point curves total 7.5-8.5 sqrt(area)
                assert result.fmaps.C_MN.shape == (size, size)
    # within 10% of NO17 at 2 curves: near-degenerate eigenvectors differ between eigensolver runs by a few %
    assert errors["combined", 2] <= min(0.034, 0.7 * errors["curves", 2], 1.1 * errors["no17", 2]), errors
    assert errors["combined", 10] <= min(0.025, errors["curves", 10], 1.05 * errors["no17", 10]), errors


def test_one_curve_on_faust_keeps_left_and_right(faust):
    # The protocol for one curve (issue 35): endpoints chosen on the target (a farthest-point pair among
    # ground-truth vertices: the top of the head and a foot), the source's their true images; the reverse map scored
    # on the source away from the endpoints. Without each curve's side in the prior one arm landed on the other:
    # 0.26 (docs/accuracy.md#one-curve-that-cannot-flip); with it 0.032.
    M, N, truth, store = faust
    swapped = GroundTruth(truth.ids_Y, truth.ids_X, truth.kind, truth.dense)
    curves = [(path_M, path_N) for path_N, path_M in ground_truth_curves(N, M, swapped, 1)]
    result = match(M, N, curves, store=store, method="combined")
    (path_M, path_N), ends = curves[0], [0, -1]
    away = ~np.isin(truth.ids_X, path_M[ends]) & ~np.isin(truth.ids_Y, path_N[ends])
    scored = GroundTruth(truth.ids_X[away], truth.ids_Y[away], truth.kind, truth.dense)
    assert score(result, scored)["target_to_source"]["mean_area"] <= 0.06


@pytest.fixture
def sessions(tmp_path, shapes):
    store = Store(tmp_path / "data")
    params = registry.get("basis", "laplace-beltrami").parse_params({}).model_dump()
    M, bM, N, bN = shapes
    ids = [store.put_mesh(mesh) for mesh in (M, N)]
    for mesh_id, basis in zip(ids, (bM, bN), strict=True):
        store.put_basis(mesh_id, basis, "laplace-beltrami", params)
    return store, ids


def editor_on(store):
    records = sessions_of(store)
    return SessionEditor(records, LiveSessions(store, records))


def test_sessions_keep_their_energy_across_a_reload(sessions):
    store, (source, target) = sessions
    editor = editor_on(store)
    created = {
        energy: editor.create(SessionCreate(source=source, target=target, k=K, **energy_field))
        for energy, energy_field in (("combined", {}), ("curves", {"energy": "curves"}))
    }
    assert {energy: record.energy for energy, record in created.items()} == {"combined": "combined", "curves": "curves"}
    spec = CurveSpec(source=list(ENDPOINTS[0]), target=list(ENDPOINTS[0]))
    maps = {}
    for energy, record in created.items():
        editor.add_curve(record.id, spec)
        maps[energy] = editor.maps(record.id)[0]
    reloaded = editor_on(store)  # another process: records from disk, solvers rebuilt
    for energy, record in created.items():
        C_MN, _, stored = reloaded.maps(record.id)
        assert stored.energy == energy
        assert np.allclose(C_MN, maps[energy], rtol=0, atol=1e-12)
    assert not np.allclose(maps["combined"], maps["curves"], atol=1e-3)


def test_a_record_written_before_energies_existed_keeps_the_curve_energy(sessions):
    store, (source, target) = sessions
    records = sessions_of(store)
    old = SessionRecord(
        id="old",
        source=source,
        target=target,
        k=K,
        alpha=100.0,
        samples=100,
        tracer="geodesic",
        basis_plugin="laplace-beltrami",
        basis_params={},
        created_at=0.0,
        updated_at=0.0,
    )
    on_disk = old.model_dump(mode="json")
    on_disk.pop("energy")
    assert SessionRecord.model_validate(on_disk).energy == "curves"
    records.create(SessionRecord.model_validate(on_disk))
    pair = load_pair(store, records.read("old"))
    with build_solver(records.read("old"), pair) as solver:
        assert type(solver) is CurveMapSolver


def test_live_sessions_on_big_shapes_leave_the_prior_out(sessions):
    store, (source, target) = sessions
    records = sessions_of(store)
    for limit, weight in ((10, 0.0), (100_000, DEFAULT_PRIOR_WEIGHT)):  # the ellipsoids have 4,098 vertices
        live = LiveSessions(store, records, prior_max_vertices=limit)
        editor = SessionEditor(records, live)
        record = editor.create(SessionCreate(source=source, target=target, k=K))
        editor.add_curve(record.id, CurveSpec(source=list(ENDPOINTS[0]), target=list(ENDPOINTS[0])))
        with live.using(record.id) as session:
            assert session.solver.prior_weight == weight
        live.close()
