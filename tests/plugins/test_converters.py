"""Refining converters (icp, zoomout, rhm) on real shapes with ground truth: the refinement issue's acceptance.

Every case starts from the 10-curve maps of the core issue's protocol (curvefm.evaluation.protocol). Iteration counts of
``rhm`` are cut to 30 (the defaults stop after about 110) to keep this file near two minutes; the benchmark
(benchmarks/bench_converters.py) runs the defaults.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
import pytest

from curvefm import registry
from curvefm.errors import CurvefmError
from curvefm.evaluation import evaluate_map, ground_truth_curves, ground_truth_for, score
from curvefm.fmap import DEFAULT_ALPHA, DEFAULT_K, DEFAULT_SAMPLES, FunctionalMaps
from curvefm.geometry import load_mesh
from curvefm.matching import MatchResult, convert, match
from curvefm.plugins import converters
from curvefm.plugins.rhm import (
    ANCHOR_RADIUS,
    ENERGY_WINDOW,
    PIN_WEIGHT,
    RhmParams,
    prepare_shape,
    reversible_harmonic_maps,
)
from curvefm.pointwise import (
    AUTO_SAMPLES,
    CurvePins,
    PointwiseMaps,
    closest_points,
    edge_stretch,
    refinement_samples,
)
from curvefm.pointwise.curve_pins import FREE
from curvefm.progress import Cancelled, no_progress
from curvefm.session import CurveRecord, CurveSpec, SessionRecord
from curvefm.store import Store
from curvefm.workers.embedded import EmbeddedQueue

FAUST = ("faust/tr_reg_000.off", "faust/tr_reg_011.off")
CAT_LION = ("nonisometric/pyfm_cat_lion/cat-00.off", "nonisometric/pyfm_cat_lion/lion-00.off")
SHORT_RHM = {"max_iterations": 30}


@dataclasses.dataclass
class Case:
    result: MatchResult  # with the nearest-neighbor maps
    truth: object
    baseline: float  # nearest-neighbor error, source -> target, by sqrt(area)
    curves: list


@pytest.fixture(scope="module")
def store(tmp_path_factory) -> Store:
    return Store(tmp_path_factory.mktemp("store"))


def ten_curve_case(shared_data: Path, store: Store, pair: tuple[str, str]) -> Case:
    source, target = shared_data / pair[0], shared_data / pair[1]
    mesh_M, mesh_N = load_mesh(source), load_mesh(target)
    truth = ground_truth_for(source, target, mesh_M, mesh_N)
    curves = ground_truth_curves(mesh_M, mesh_N, truth, 10)
    result = match(mesh_M, mesh_N, curves, store=store, method="curves")  # the start of the README's refinement table
    return Case(result, truth, score(result, truth)["source_to_target"]["mean_area"], curves)


@pytest.fixture(scope="module")
def faust(shared_data, store) -> Case:
    return ten_curve_case(shared_data, store, FAUST)


@pytest.fixture(scope="module")
def cat_lion(shared_data, store) -> Case:
    return ten_curve_case(shared_data, store, CAT_LION)


def refined_error(case: Case, converter: str, params: dict, pair=None, fmaps=None, progress=no_progress) -> float:
    plugin, parsed = registry.load("converter", converter, params)
    maps = plugin.run(pair or case.result.pair, fmaps or case.result.fmaps, parsed, progress)
    mesh_M, mesh_N = case.result.pair.meshes
    assert maps.p2p_NM.shape == (mesh_N.n_vertices,)
    assert maps.p2p_MN.shape == (mesh_M.n_vertices,)
    return evaluate_map(maps.p2p_MN, case.truth, mesh_N).mean_area


@pytest.fixture(scope="module")
def faust_zoomout_error(faust) -> float:
    """ZoomOut with its defaults, which on FAUST (6,890 vertices) iterate on every vertex."""
    return refined_error(faust, "zoomout", {})


def test_the_automatic_embedding_keeps_the_candidate_that_stretches_edges_least(shared_data, store):
    """cat -> lion with 2 curves and the default method: the single-map embedding is far better there (the reverse
    map is poor on this non-isometric pair) and ``auto`` finds that without ground truth (before the orthogonal
    steps, which start from its choice)."""
    source, target = shared_data / CAT_LION[0], shared_data / CAT_LION[1]
    mesh_M, mesh_N = load_mesh(source), load_mesh(target)
    truth = ground_truth_for(source, target, mesh_M, mesh_N)
    result = match(mesh_M, mesh_N, ground_truth_curves(mesh_M, mesh_N, truth, 2), store=store)
    errors, stretch = {}, {}
    for embedding in ("auto", "both", "single"):
        plugin, parsed = registry.load("converter", "nearest-neighbor", {"embedding": embedding, "orthogonal_steps": 0})
        maps = plugin.run(result.pair, result.fmaps, parsed)
        errors[embedding] = evaluate_map(maps.p2p_MN, truth, mesh_N).mean_area
        stretch[embedding] = edge_stretch(mesh_M, mesh_N, maps.p2p_MN)
    assert stretch["auto"] == min(stretch["both"], stretch["single"])
    assert errors["auto"] <= min(0.038, 0.75 * errors["both"]), errors  # 0.038: issue 13's target


def test_big_meshes_get_the_orthogonal_steps_on_area_samples(faust, monkeypatch):
    """Where the conversion's search is approximate (big meshes; forced here on FAUST) the map is stepped as on small
    meshes, the steps iterated on area-drawn samples of each shape (fewer than FAUST's vertices here) and every
    vertex matched once at the end (issue 37): better than the unstepped conversion big meshes got before, and
    close to the steps on every vertex."""
    on_every_vertex = refined_error(faust, "nearest-neighbor", {})
    stepped = []
    monkeypatch.setattr(converters, "uses_approximate", lambda rows, queries: True)
    monkeypatch.setattr(converters, "STEP_SAMPLES", 5000)
    steps = converters.sampled_orthogonal_steps
    monkeypatch.setattr(converters, "sampled_orthogonal_steps", lambda *args: stepped.append(args) or steps(*args))
    unstepped = refined_error(faust, "nearest-neighbor", {"orthogonal_steps": 0})
    assert not stepped
    on_samples = refined_error(faust, "nearest-neighbor", {})
    assert len(stepped) == 2 and all(len(args[1].ids) == 5000 for args in stepped)
    assert on_samples < unstepped, (on_samples, unstepped)
    assert on_samples <= 1.05 * on_every_vertex, (on_samples, on_every_vertex)


@pytest.mark.parametrize("converter, params", [("icp", {}), ("zoomout", {"samples": 2000}), ("rhm", SHORT_RHM)])
def test_faust_every_converter_beats_nearest_neighbor(faust, converter, params):
    error = refined_error(faust, converter, params)
    assert error < faust.baseline, (error, faust.baseline)
    if converter == "zoomout":
        assert error <= 0.7 * faust.baseline, (error, faust.baseline)


def test_faust_zoomout_beats_nearest_neighbor_by_30_percent(faust, faust_zoomout_error):
    assert faust_zoomout_error <= 0.7 * faust.baseline, (faust_zoomout_error, faust.baseline)


def test_faust_is_refined_on_every_vertex_by_default_and_sampled_zoomout_stays_close(faust, faust_zoomout_error):
    mesh_M, mesh_N = faust.result.pair.meshes
    assert refinement_samples(mesh_M, mesh_N, None) is None
    ids_M, ids_N = refinement_samples(mesh_M, mesh_N, None, dense_up_to=mesh_M.n_vertices - 1)
    assert len(ids_M) == len(ids_N) == AUTO_SAMPLES
    dense = faust_zoomout_error
    sampled = refined_error(faust, "zoomout", {"dense_up_to": 0})  # as on a big mesh: AUTO_SAMPLES samples
    # measured: 0.0140 against 0.0111 here (FAUST's vertices crowd the hands and face, where spread samples are
    # sparse); on the 110k subdivided pair sampled and dense agree within 2% (benchmarks/bench_converters.py)
    assert sampled <= 1.3 * dense, (sampled, dense)
    assert sampled <= 0.7 * faust.baseline, (sampled, faust.baseline)


def test_sampled_icp_beats_nearest_neighbor(faust):
    error = refined_error(faust, "icp", {"samples": 2000})
    assert error < faust.baseline, (error, faust.baseline)


def test_rhm_on_decimated_copies_beats_nearest_neighbor(faust):
    """As on a big mesh: RHM on 2,000-vertex copies, then one projection of every vertex."""
    messages = []
    params = SHORT_RHM | {"init": "nearest-neighbor", "dense_up_to": 0, "coarse_vertices": 2000}
    error = refined_error(faust, "rhm", params, progress=lambda fraction, message: messages.append(message))
    assert error < faust.baseline, (error, faust.baseline)
    assert messages[-1] == "projecting every vertex"


def test_cat_to_lion_rhm_beats_nearest_neighbor(cat_lion):
    error = refined_error(cat_lion, "rhm", SHORT_RHM)
    assert error < cat_lion.baseline, (error, cat_lion.baseline)


def test_rhm_keeps_every_image_within_the_anchor_radius_of_the_nearest_neighbour_start(faust):
    """RHM may refine the start locally but not carry a vertex across the shape: after every projection an image
    farther than ``anchor_radius`` (geodesic embedding, unit area) from the nearest-neighbour image goes back there,
    except the curves' ends, which stay pinned. Without the anchor the same iterations move some images farther."""
    # the nearest-neighbour maps without the orthogonal steps: from the stepped ones no image of these iterations goes
    # farther than the radius even unanchored (issue 35), which would leave the anchor's effect untested
    pair = faust.result.pair
    plugin, parsed = registry.load("converter", "nearest-neighbor", {"orthogonal_steps": 0})
    start = plugin.run(pair, faust.result.fmaps, parsed)
    params = RhmParams(**SHORT_RHM)
    shapes = prepare_shape(pair.mesh_M, params), prepare_shape(pair.mesh_N, params)
    pins = CurvePins.from_curves(pair.mesh_M, pair.mesh_N, faust.result.paths)
    farthest = {}
    for radius in (0.0, ANCHOR_RADIUS):
        anchored = params.model_copy(update={"anchor_radius": radius})
        MN, NM, _ = reversible_harmonic_maps(start, *shapes, anchored, pins=pins, anchor=start)
        free_M, free_N = pins.M_to_N == FREE, pins.N_to_M == FREE
        np.testing.assert_array_equal(MN.p2p[~free_M], pins.M_to_N[~free_M])
        np.testing.assert_array_equal(NM.p2p[~free_N], pins.N_to_M[~free_N])
        farthest[radius] = max(
            np.linalg.norm(shapes[1].X[MN.p2p] - shapes[1].X[start.p2p_MN], axis=1)[free_M].max(),
            np.linalg.norm(shapes[0].X[NM.p2p] - shapes[0].X[start.p2p_NM], axis=1)[free_N].max(),
        )
    assert farthest[ANCHOR_RADIUS] <= ANCHOR_RADIUS < farthest[0.0], farthest


def test_rhm_pin_weight_ties_the_pinned_ends_continuous_images_to_their_pins(faust):
    """The curves' ends are exact: with ``pin_weight`` their continuous images (which carry the smoothness and the
    reversibility) are drawn to their pins from the first iterations, where the coupling alone (beta 0.005 rising)
    leaves them farther off (after 3 iterations on FAUST, 10 curves: 0.0082 against 0.0163, unit area)."""
    pair = faust.result.pair
    plugin, parsed = registry.load("converter", "nearest-neighbor", None)
    start = plugin.run(pair, faust.result.fmaps, parsed)
    params = RhmParams(max_iterations=3, min_iterations=ENERGY_WINDOW + 1)
    shapes = prepare_shape(pair.mesh_M, params), prepare_shape(pair.mesh_N, params)
    pins = CurvePins.from_curves(pair.mesh_M, pair.mesh_N, faust.result.paths)
    pinned = pins.M_to_N != FREE
    off = {}
    for weight in (0.0, PIN_WEIGHT):
        MN, _, _ = reversible_harmonic_maps(start, *shapes, params.model_copy(update={"pin_weight": weight}), pins=pins)
        off[weight] = np.linalg.norm(MN.X[pinned] - shapes[1].X[pins.M_to_N[pinned]], axis=1).mean()
    assert off[PIN_WEIGHT] < 0.7 * off[0.0], off


def test_rhm_reports_progress_and_stops_when_cancelled(faust):
    seen = []

    def progress(fraction: float, message: str) -> None:
        seen.append((fraction, message))
        if message.startswith("RHM iteration 3 "):
            raise Cancelled

    with pytest.raises(Cancelled):
        refined_error(faust, "rhm", {"init": "nearest-neighbor"}, progress=progress)
    fractions = [f for f, _ in seen]
    assert fractions == sorted(fractions) and 0 <= fractions[0] and fractions[-1] <= 1
    assert [m for _, m in seen if m.startswith("RHM iteration")][-1].startswith("RHM iteration 3 ")


def test_zoomout_computes_a_larger_basis_than_the_sessions(faust):
    small = faust.result.pair.truncated(40)
    fmaps = FunctionalMaps(faust.result.fmaps.C_MN[:40, :40], faust.result.fmaps.C_NM[:40, :40])
    messages = []
    params = {"k_final": 60, "step": 10}
    error = refined_error(faust, "zoomout", params, small, fmaps, lambda f, m: messages.append(m))
    assert any("computing a 60-function basis (the session's has 40)" in m for m in messages)
    assert error < faust.baseline


@pytest.mark.parametrize("iterate_on", [{}, {"samples": 600}], ids=["every vertex", "samples"])
def test_zoomout_stages_are_zoomout_stopped_at_smaller_sizes(faust, iterate_on):
    pair, fmaps, paths = faust.result.pair, faust.result.fmaps, faust.result.paths
    params = {"k_init": 20, "k_final": 40, "step": 5} | iterate_on
    plugin, parsed = registry.load("converter", "zoomout", params)
    stages = list(plugin.convert_in_stages(pair, fmaps, parsed, no_progress, paths))
    assert [label for label, _ in stages] == ["k = 40", "k = 30", "k = 20"]
    for (label, maps), k_final in zip(stages, (40, 30, 20), strict=True):
        _, stopped = registry.load("converter", "zoomout", params | {"k_final": k_final})
        _, alone = next(plugin.convert_in_stages(pair, fmaps, stopped, no_progress, paths))
        assert np.array_equal(maps.p2p_MN, alone.p2p_MN) and np.array_equal(maps.p2p_NM, alone.p2p_NM), label


def staged_converter(*stages: str) -> registry.ConverterPlugin:
    """A refining converter whose stages, most refined first, are the ``nearest-neighbor`` maps (``"start"``) or
    maps that send every vertex to vertex 0 (``"collapsed"``, worse on every intrinsic figure)."""

    def run_stages(pair, fmaps, params, progress):
        for i, kind in enumerate(stages):
            if kind == "start":
                yield f"stage {i}", registry.load("converter", "nearest-neighbor", None)[0].run(pair, fmaps, params)
            else:
                n_M, n_N = pair.mesh_M.n_vertices, pair.mesh_N.n_vertices
                yield f"stage {i}", PointwiseMaps(p2p_NM=np.zeros(n_N, int), p2p_MN=np.zeros(n_M, int))

    def run(pair, fmaps, params, progress):
        return next(run_stages(pair, fmaps, params, progress))[1]

    nearest = registry.get("converter", "nearest-neighbor")
    return registry.ConverterPlugin(
        name="staged", description="test stages", Params=nearest.Params, run=run, stages=run_stages
    )


def test_the_guard_returns_the_first_earlier_stage_that_makes_no_figure_worse(faust):
    converter = staged_converter("collapsed", "collapsed", "start", "collapsed")
    messages = []
    result = convert(
        faust.result.pair,
        faust.result.fmaps,
        converter,
        converter.parse_params(None),
        lambda _, message: messages.append(message),
    )
    assert [m.rsplit(" ", 2)[-2:] for m in messages if "checking" in m] == [["stage", "1"], ["stage", "2"]]
    assert result.kept == "stopped" and "stopped at stage 2" in result.reason and "coverage" in result.reason
    assert result.quality["stopped"]["at"] == "stage 2"
    assert result.quality["stopped"]["coverage"] == result.quality["initial"]["coverage"]
    assert result.quality["refined"]["coverage"] < 0.01  # the whole refinement's figures, as reported
    collapsed_only = staged_converter("collapsed", "collapsed")
    result = convert(faust.result.pair, faust.result.fmaps, collapsed_only, collapsed_only.parse_params(None))
    assert result.kept == "initial" and set(result.quality) == {"initial", "refined"}


def faust_session(faust: Case, store: Store) -> SessionRecord:
    mesh_M, mesh_N = faust.result.pair.meshes
    curves = []
    for i, (path_M, path_N) in enumerate(faust.curves):
        ids_M, ids_N = mesh_M.file_ids[path_M].tolist(), mesh_N.file_ids[path_N].tolist()
        spec = CurveSpec(source=ids_M, target=ids_N, explicit=True)
        curves.append(CurveRecord(id=f"c{i}", spec=spec, tracer="geodesic", path_source=ids_M, path_target=ids_N))
    return SessionRecord(
        id="refinetest",
        source=store.put_mesh(mesh_M),
        target=store.put_mesh(mesh_N),
        k=DEFAULT_K,
        alpha=DEFAULT_ALPHA,
        samples=DEFAULT_SAMPLES,
        tracer="geodesic",
        basis_plugin="laplace-beltrami",
        basis_params={"laplacian": "cotangent"},
        curves=curves,
        created_at=time.time(),
        updated_at=time.time(),
    )


def run_refine_job(store: Store, record: SessionRecord, converter: str, params: dict):
    """The refine job on the in-process queue; ``(final job info, progress reports seen)``."""
    queue = EmbeddedQueue(store.root, max_workers=1)
    try:
        kwargs = {"data_dir": str(store.root), "session": record.model_dump(), "converter": converter, "params": params}
        job_id = queue.submit("refine", kwargs).id
        reports = []
        while (info := queue.get(job_id)).state not in ("finished", "failed", "canceled"):
            reports.append((info.progress, info.message))
            time.sleep(0.05)
    finally:
        queue.close()
    assert info.state == "finished", info.error
    return info, reports


def job_error(store: Store, faust: Case, job_id: str) -> float:
    mesh_M, mesh_N = faust.result.pair.meshes
    p2p_file = np.load(store.root / "results" / job_id / "p2p_source_to_target.npy")
    return evaluate_map(mesh_N.internal_ids(p2p_file[mesh_M.file_ids]), faust.truth, mesh_N).mean_area


def test_refine_job_runs_rhm_with_progress_through_the_job_api(faust, store):
    info, reports = run_refine_job(store, faust_session(faust, store), "rhm", SHORT_RHM)
    assert any(m.startswith("RHM iteration") for _, m in reports)
    assert [p for p, _ in reports] == sorted(p for p, _ in reports)
    assert info.result["kept"] == "refined", info.result["reason"]
    refined = info.result["quality"]["refined"]
    mesh_M, mesh_N = faust.result.pair.meshes
    p2p_file = np.load(store.root / "results" / info.id / "p2p_source_to_target.npy")
    p2p_MN = mesh_N.internal_ids(p2p_file[mesh_M.file_ids])
    for path_M, path_N in faust.result.paths:  # the curves' ends are pinned; their interiors are free
        assert p2p_MN[path_M[0]] == path_N[0] and p2p_MN[path_M[-1]] == path_N[-1]
    assert refined["curve_residual"] > 0
    assert job_error(store, faust, info.id) < faust.baseline


def test_a_refinement_that_makes_the_map_worse_is_not_returned(faust, store):
    # square 50 x 50 ICP drifts on FAUST (see plugins/icp.py): measured 0.028 -> 0.10 without the check
    plugin, parsed = registry.load("converter", "icp", {"k": 50, "k_image": 50})
    drifted = evaluate_map(
        plugin.run(faust.result.pair, faust.result.fmaps, parsed).p2p_MN, faust.truth, faust.result.pair.mesh_N
    ).mean_area
    assert drifted > 1.5 * faust.baseline
    info, _ = run_refine_job(store, faust_session(faust, store), "icp", {"k": 50, "k_image": 50})
    assert info.result["kept"] == "initial" and "made the map worse" in info.result["reason"]
    assert set(info.result["quality"]) == {"initial", "refined"}
    assert job_error(store, faust, info.id) <= 1.02 * faust.baseline  # the start: the session solver's maps


def test_closest_points_on_an_embedded_mesh_match_dense_sampling():
    rng = np.random.default_rng(3)
    grid = np.stack(np.meshgrid(np.arange(6), np.arange(6), indexing="ij"), -1).reshape(-1, 2).astype(float)
    faces = np.array([[i * 6 + j, i * 6 + j + 1, (i + 1) * 6 + j] for i in range(5) for j in range(5)])
    points = np.hstack([grid, rng.normal(scale=0.3, size=(36, 6))])  # a bent sheet in R^8
    queries = points[rng.integers(0, 36, 40)] + rng.normal(scale=0.4, size=(40, 8))
    corners, weights = closest_points(points, faces, queries, candidates=36)
    found = np.linalg.norm(queries - np.einsum("qc,qcd->qd", weights, points[corners]), axis=1)
    assert np.allclose(weights.sum(axis=1), 1) and (weights >= -1e-12).all()
    s, t = (a.ravel() for a in np.meshgrid(np.linspace(0, 1, 41), np.linspace(0, 1, 41)))
    s, t = s[s + t <= 1], t[s + t <= 1]
    tri = points[faces]
    dense = tri[:, :1] + s[None, :, None] * (tri[:, 1:2] - tri[:, :1]) + t[None, :, None] * (tri[:, 2:] - tri[:, :1])
    best = np.linalg.norm(queries[:, None, None] - dense[None], axis=-1).min(axis=(1, 2))
    assert (found <= best + 1e-9).all() and (best - found < 0.05).all()


@pytest.mark.parametrize(
    "converter, params, field",
    [
        ("icp", {"k": 60, "k_image": 40}, "k_image"),
        ("icp", {"iterations": 0}, "iterations"),
        ("zoomout", {"k_init": 50, "k_final": 30}, "k_final"),
        ("zoomout", {"samples": 100}, "samples"),
        ("zoomout", {"search": "faiss"}, "search"),
        ("icp", {"samples": 60}, "samples"),
        ("nearest-neighbor", {"search": "hnsw"}, "search"),
        ("zoomout", {"step": "big"}, "step"),
        ("rhm", {"alpha": 1.5}, "alpha"),
        ("rhm", {"projection": "edge"}, "projection"),
        ("rhm", {"init_zoomout": {"k_init": 1}}, "init_zoomout.k_init"),
        ("rhm", {"beta": 0.1, "beta_max": 0.01}, "beta_max"),
        ("rhm", {"iterations": 10}, "iterations"),
    ],
)
def test_bad_parameters_are_refused_naming_the_field(converter, params, field):
    with pytest.raises(CurvefmError, match=rf"bad parameters for '{converter}': .*{field}"):
        registry.get("converter", converter).parse_params(params)
