"""The pairs held out of the reproduce suite (``HELD_OUT_PAIRS``) check defaults chosen on the suite and never choose
one: no experiment picks them by default or by its own list, and no recorded tuning result holds them."""

import argparse
import json
from pathlib import Path

from curvefm.evaluation.reproduce.datasets import FULL_PAIRS, HELD_OUT_PAIRS, Pair
from experiments.common import add_pair_arguments, chosen_pairs

EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"


def files_of(pair: Pair) -> frozenset[str]:
    return frozenset((pair.source, pair.target))


def test_no_held_out_pair_is_in_the_suite_either_way_round():
    assert len(set(HELD_OUT_PAIRS)) == len(HELD_OUT_PAIRS) == 12
    assert not {files_of(p) for p in HELD_OUT_PAIRS} & {files_of(p) for p in FULL_PAIRS}


def test_experiments_run_the_suite_unless_asked_for_the_held_out_pairs():
    parser = argparse.ArgumentParser()
    add_pair_arguments(parser)
    assert chosen_pairs(parser.parse_args([])) == list(FULL_PAIRS)
    assert chosen_pairs(parser.parse_args(["--pairs", "held-out"])) == list(HELD_OUT_PAIRS)
    names = ["cat0->dog0", "tr_reg_060->tr_reg_071"]
    assert [p.name for p in chosen_pairs(parser.parse_args(["--pairs", "held-out", "--names", *names]))] == names
    # only that option reaches the list: no experiment imports it to loop over on its own
    using = [f.name for f in EXPERIMENTS.glob("*.py") if "HELD_OUT_PAIRS" in f.read_text()]
    assert using == ["common.py"]


def recorded_pairs(value, held_out_part: bool = False):
    """``(pair, recorded in a part labelled held-out)`` for every row of an experiment's JSON naming a pair."""
    if isinstance(value, dict):
        held_out_part = held_out_part or value.get("pairs") == "held-out"
        if isinstance(value.get("pair"), str):
            yield (value.get("dataset"), value["pair"]), held_out_part
        for key, item in value.items():
            yield from recorded_pairs(item, held_out_part or key == "held_out")
    elif isinstance(value, list):
        for item in value:
            yield from recorded_pairs(item, held_out_part)


def is_held_out(dataset: str | None, pair: str) -> bool:
    """Rows name a pair by its dataset and name, or by its files (``faust/a.off -> faust/b.off``)."""
    return any((dataset, pair) == (p.dataset, p.name) or pair == f"{p.source} -> {p.target}" for p in HELD_OUT_PAIRS)


def test_held_out_pairs_appear_only_in_results_recorded_as_checks():
    results = sorted(EXPERIMENTS.glob("*.json"))
    assert len(results) > 10
    checks = 0
    for path in results:
        for (dataset, pair), labelled in recorded_pairs(json.loads(path.read_text())):
            if is_held_out(dataset, pair):
                assert labelled or path.stem.endswith("_held_out"), (path.name, pair)
                checks += 1
    assert checks > 0  # the held-out results are there, and recognised
