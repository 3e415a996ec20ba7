"""Issue 35's two- and ten-curve bounds on FAUST 000 -> 011 with the curves' endpoints chosen on the target: the
default ``curvefm match`` (combined method, ``nearest-neighbor`` conversion with its orthogonal steps), both maps
scored away from the curves' ends."""

import pytest

from curvefm.evaluation import ground_truth_curves, ground_truth_for, score, truth_to_score
from curvefm.geometry import load_mesh
from curvefm.matching import match
from curvefm.store import Store

SOURCE, TARGET = "faust/tr_reg_000.off", "faust/tr_reg_011.off"
BOUND = 0.034  # issue 35, each direction
TEN_CURVE_BOUND = 0.025


@pytest.fixture(scope="module")
def faust(shared_data, tmp_path_factory):
    M, N = load_mesh(shared_data / SOURCE), load_mesh(shared_data / TARGET)
    truth = ground_truth_for(shared_data / SOURCE, shared_data / TARGET, M, N)
    return M, N, truth, Store(tmp_path_factory.mktemp("store"))


def curves_on_target(faust, count: int):
    M, N, truth, store = faust
    curves = ground_truth_curves(M, N, truth, count, endpoints_on="target")
    return M, N, curves, truth_to_score(truth, curves, 0, "target"), store


@pytest.fixture(scope="module")
def two_curves(faust):
    return curves_on_target(faust, 2)


def errors(case, steps: int | None = None, size: int | None = None) -> dict[str, float]:
    M, N, curves, scored, store = case
    params = None if steps is None else {"orthogonal_steps": steps}
    result = match(M, N, curves, store=store, converter_params=params)
    if size is not None:
        assert result.fmaps.C_MN.shape == (size, size)
    return {direction: e["mean_area"] for direction, e in score(result, scored).items()}


def test_two_curves_from_the_target_meet_the_bound_both_ways(two_curves):
    default, without_steps = errors(two_curves), errors(two_curves, steps=0)
    assert max(default.values()) <= BOUND, default
    # the orthogonal steps are what meets it: plain nearest neighbours miss it target -> source
    assert without_steps["target_to_source"] > BOUND, without_steps
    assert all(default[d] < without_steps[d] for d in default), (default, without_steps)


def test_ten_curves_gain_from_steps_on_the_whole_maps_leading_block_both_ways(faust):
    # the whole 120 x 120 map (the curves total more than sqrt(k / pi)) is converted from its 90 x 90 block and
    # stepped at 90 x 120: measured 0.0160 / 0.0156 against 0.0186 / 0.0199 converted whole without steps
    # (docs/decisions.md#the-whole-map-from-its-leading-block)
    case = curves_on_target(faust, 10)
    default, without_steps = errors(case, size=120), errors(case, steps=0, size=120)
    assert max(default.values()) <= TEN_CURVE_BOUND, default
    assert all(default[d] < 0.95 * without_steps[d] for d in default), (default, without_steps)
