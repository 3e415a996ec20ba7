"""The combined energy's rules for non-isometric pairs: the landmark distortion measured from the curves' endpoints,
and the curve energy alone from ``CURVES_ALONE_FROM`` curves on where it exceeds its threshold, in the ``combined``
method and in a session's solvers alike; and from full size on, the high frequencies damped where the spectra
differ."""

import numpy as np
import pytest
from support.shapes import basis_of, ellipsoid

from curvefm import registry
from curvefm.evaluation import ground_truth_for
from curvefm.evaluation.protocol import CurvePool
from curvefm.fmap import (
    DEFAULT_ALPHA,
    FULL_SIZE_ALPHA,
    FULL_SIZE_CURVES,
    FULL_SIZE_KERNEL_WEIGHT,
    NON_ISOMETRIC_DISTORTION,
    NON_ISOMETRIC_SPECTRA,
    CombinedMapSolver,
    CurveMapSolver,
    Hints,
    curves_alone_suffice,
)
from curvefm.fmap.combined import (
    CURVES_ALONE_FROM,
    HIGH_FREQUENCY_DAMPING,
    biharmonic_distances,
    landmark_distortion,
    spectral_mismatch,
)
from curvefm.geometry import load_mesh, shortest_path
from curvefm.progress import no_progress
from curvefm.records.sessions import sessions_of
from curvefm.session import CurveSpec, LiveSessions, SessionCreate, SessionEditor
from curvefm.spectral import ShapePair
from curvefm.store import Store

K = 30
STRONG_STRETCH = (2.5, 0.45, 0.3)  # distortion 0.81 against the default ellipsoid with these landmarks
MILD_STRETCH = (1.1, 0.6, 0.55)  # 0.05
LANDMARKS = np.random.default_rng(0).choice(24 * 48, 12, replace=False)


def endpoints(count):
    """``count`` pairs of LANDMARKS (vertex i <-> vertex i on both ellipsoids), consecutive ones joined."""
    return [
        (LANDMARKS[i % len(LANDMARKS)], LANDMARKS[(i + 1 + i // len(LANDMARKS)) % len(LANDMARKS)]) for i in range(count)
    ]


def curves_between(M, N, count):
    return [(shortest_path(M.edge_graph, a, b), shortest_path(N.edge_graph, a, b)) for a, b in endpoints(count)]


@pytest.fixture(scope="module")
def bases():
    return {
        name: basis_of(ellipsoid(**shape), K)
        for name, shape in (
            ("M", {}),
            ("scaled", {"scale": 3.0}),
            ("mild", {"radii": MILD_STRETCH}),
            ("strong", {"radii": STRONG_STRETCH}),
        )
    }


def test_the_landmark_distortion_ignores_scale_and_grows_with_stretch(bases):
    same = np.c_[LANDMARKS, LANDMARKS]
    assert landmark_distortion(bases["M"], bases["scaled"], same) < 1e-9
    mild, strong = (landmark_distortion(bases["M"], bases[name], same) for name in ("mild", "strong"))
    assert 0.01 < mild < NON_ISOMETRIC_DISTORTION < strong
    assert landmark_distortion(bases["M"], bases["strong"], same[:1]) == 0.0  # no pair of landmarks: nothing measured


def test_the_spectral_mismatch_ignores_scale_and_grows_with_stretch(bases):
    assert spectral_mismatch(bases["M"], bases["M"]) == 0.0
    assert spectral_mismatch(bases["M"], bases["scaled"]) < 1e-6  # the bases are of the shapes at unit area
    mild, strong = (spectral_mismatch(bases["M"], bases[name]) for name in ("mild", "strong"))
    assert 0.01 < mild < strong
    assert spectral_mismatch(bases["M"].truncated(10), bases["strong"]) == spectral_mismatch(
        bases["M"].truncated(10), bases["strong"].truncated(10)
    )  # only the eigenpairs both hold


def test_biharmonic_distances_are_those_of_the_spectral_embedding(bases):
    basis, vertices = bases["M"], LANDMARKS[:5]
    embedded = basis.evecs[vertices, 1:] / basis.evals[1:]
    expected = np.linalg.norm(embedded[:, None] - embedded[None, :], axis=2)
    np.testing.assert_allclose(biharmonic_distances(basis, vertices), expected, atol=1e-8)  # sqrt of rounding


def test_curves_alone_suffice_from_enough_curves_on(bases):
    M, strong, mild = ellipsoid(), ellipsoid(radii=STRONG_STRETCH), ellipsoid(radii=MILD_STRETCH)
    for count, expected in ((CURVES_ALONE_FROM - 1, False), (CURVES_ALONE_FROM, True), (FULL_SIZE_CURVES, True)):
        assert curves_alone_suffice(bases["M"], bases["strong"], curves_between(M, strong, count)) == expected, count
    ten = curves_between(M, strong, CURVES_ALONE_FROM)
    assert not curves_alone_suffice(bases["M"], bases["mild"], curves_between(M, mild, CURVES_ALONE_FROM))
    assert not curves_alone_suffice(bases["M"], bases["strong"], ten, threshold=1.0)


@pytest.fixture(scope="module")
def stretched_pair(bases):
    return ShapePair(ellipsoid(), ellipsoid(radii=STRONG_STRETCH), bases["M"], bases["strong"])


def maps_of(pair, method, curves, **params):
    plugin, parsed = registry.load("method", method, params)
    return plugin.run(pair, Hints.from_curves(curves), parsed, no_progress)


@pytest.mark.parametrize("count", [CURVES_ALONE_FROM, FULL_SIZE_CURVES])
def test_the_combined_method_solves_the_curve_energy_alone_on_a_strongly_non_isometric_pair(stretched_pair, count):
    curves = curves_between(stretched_pair.mesh_M, stretched_pair.mesh_N, count)
    alone = maps_of(stretched_pair, "curves", curves)
    combined = maps_of(stretched_pair, "combined", curves)
    np.testing.assert_allclose(combined.C_NM, alone.C_NM, atol=1e-12)
    np.testing.assert_allclose(combined.C_MN, alone.C_MN, atol=1e-12)
    kept = maps_of(stretched_pair, "combined", curves, non_isometric_distortion=10.0)  # the rule off
    assert np.abs(kept.C_NM - alone.C_NM[: len(kept.C_NM), : len(kept.C_NM)]).max() > 1e-3


def test_from_full_size_a_non_isometric_pairs_map_has_its_high_frequencies_damped():
    """Handed out whole (from FULL_SIZE_CURVES curves), the map keeps the prior's 50 x 50 block and damps the rest
    where the spectra show the pair non-isometric; an isometric pair's map stays as solved."""
    k = 60  # above the prior's block
    for N, damped in ((ellipsoid(radii=STRONG_STRETCH), True), (ellipsoid(scale=3.0), False)):
        M = ellipsoid()
        pair = ShapePair(M, N, basis_of(M, k), basis_of(N, k))
        assert (spectral_mismatch(pair.basis_M, pair.basis_N) > NON_ISOMETRIC_SPECTRA) == damped
        curves = curves_between(M, N, FULL_SIZE_CURVES)
        combined = {"non_isometric_distortion": 10.0}  # the stretch would fall back to the curve energy
        handed_out = maps_of(pair, "combined", curves, **combined)
        solved = maps_of(pair, "combined", curves, non_isometric_spectra=10.0, **combined)  # the rule off
        outside = np.ones((k, k), dtype=bool)
        outside[:50, :50] = False
        for mine, whole in ((handed_out.C_NM, solved.C_NM), (handed_out.C_MN, solved.C_MN)):
            assert mine.shape == (k, k) and np.abs(whole[outside]).max() > 1e-3
            np.testing.assert_allclose(mine[~outside], whole[~outside], rtol=0, atol=1e-12)
            factor = HIGH_FREQUENCY_DAMPING if damped else 1.0
            np.testing.assert_allclose(mine[outside], factor * whole[outside], rtol=0, atol=1e-12)


def test_the_solver_states_its_size_and_weights_on_both_sides_of_the_size_switch():
    """k = 60: below FULL_SIZE_CURVES the map is handed out at the prior's 50 x 50 with the session's weights, from
    then on whole with the full-size ones; a non-isometric pair's high frequencies are damped, and it says so."""
    k = 60
    for N, damped in ((ellipsoid(scale=3.0), False), (ellipsoid(radii=STRONG_STRETCH), True)):
        M = ellipsoid()
        solver = CombinedMapSolver(M.vertices, basis_of(M, k), N.vertices, basis_of(N, k), k=k, alpha=70.0)
        curves = curves_between(M, N, FULL_SIZE_CURVES)
        solver.add_curves([(*curve, 1.0) for curve in curves[:3]])
        few = solver.effective()
        assert (few.energy, few.size, few.summary) == (
            "combined",
            50,
            f"combined; 50 x 50 until {FULL_SIZE_CURVES} curves",
        )
        assert few.weights["alpha"] == 70.0 and "not the k = 60 asked" in few.reason
        assert "high_frequency_damping" not in few.weights and solver.C_MN.shape == (50, 50)
        solver.add_curves([(*curve, 1.0) for curve in curves[3:]])
        whole = solver.effective()
        assert whole.size == 60 and solver.C_MN.shape == (60, 60)
        assert (whole.weights["alpha"], whole.weights["kernels"]) == (FULL_SIZE_ALPHA, FULL_SIZE_KERNEL_WEIGHT)
        assert whole.summary.startswith(f"combined; 60 x 60 from {FULL_SIZE_CURVES} curves, alpha 30")
        assert ("high_frequency_damping" in whole.weights) == damped == ("x 0.25" in whole.summary)
        solver.close()


def test_a_session_switches_energy_as_its_curves_cross_the_rule_and_back(tmp_path, bases, stretched_pair):
    store = Store(tmp_path / "data")
    params = registry.get("basis", "laplace-beltrami").parse_params({}).model_dump()
    ids = [store.put_mesh(mesh) for mesh in stretched_pair.meshes]
    for mesh_id, basis in zip(ids, (bases["M"], bases["strong"]), strict=True):
        store.put_basis(mesh_id, basis, "laplace-beltrami", params)
    records = sessions_of(store)
    live = LiveSessions(store, records)
    editor = SessionEditor(records, live)
    try:
        session = editor.create(SessionCreate(source=ids[0], target=ids[1], k=K)).id
        curve_ids = [
            editor.add_curve(session, CurveSpec(source=[int(a), int(b)], target=[int(a), int(b)]))[0].id
            for a, b in endpoints(CURVES_ALONE_FROM)
        ]
        assert type(live.peek(session).solver) is CurveMapSolver
        stated = editor.solve(session)
        assert (stated.energy, stated.size, stated.weights) == ("curves", K, {"alpha": DEFAULT_ALPHA})
        assert stated.summary == f"curves alone (non-isometric pair); {K} x {K}"
        assert "combined was asked" in stated.reason and "landmark distortion 0." in stated.reason
        C_MN, _, _ = editor.maps(session)
        curves = curves_between(stretched_pair.mesh_M, stretched_pair.mesh_N, CURVES_ALONE_FROM)
        np.testing.assert_allclose(C_MN, maps_of(stretched_pair, "curves", curves).C_MN, atol=1e-10)
        summary = editor.remove_curve(session, curve_ids[-1])
        assert type(live.peek(session).solver) is CombinedMapSolver
        assert (summary.solve.energy, summary.solve.summary) == ("combined", f"combined; {K} x {K}")
        reloaded = LiveSessions(store, records)  # another process builds the same energy from the record
        SessionEditor(records, reloaded).maps(session)
        assert type(reloaded.peek(session).solver) is CombinedMapSolver
        reloaded.close()
    finally:
        live.close()


@pytest.mark.parametrize(
    ("source", "target", "strong"),
    [
        ("tosca/horse0.off", "tosca/cat0.off", True),  # the descriptors mislead: curves 0.050, combined 0.133
        ("tosca/wolf0.off", "tosca/dog0.off", False),  # the most distorted pair they help
        ("nonisometric/pyfm_cat_lion/cat-00.off", "nonisometric/pyfm_cat_lion/lion-00.off", False),
    ],
)
def test_the_suites_pairs_are_told_apart_with_ten_curves(shared_data, source, target, strong):
    M, N = load_mesh(shared_data / source), load_mesh(shared_data / target)
    basis_M, basis_N = basis_of(M, 120), basis_of(N, 120)
    pool = CurvePool(M, N, ground_truth_for(shared_data / source, shared_data / target, M, N))
    for seed in range(3):
        assert curves_alone_suffice(basis_M, basis_N, pool.curves(10, seed, exact=False)) == strong, seed
