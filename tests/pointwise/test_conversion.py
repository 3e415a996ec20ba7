"""The ``nearest-neighbor`` conversion's orthogonal steps on maps of the basis's size (issue 35): such a map is
converted from its leading block, leaving the steps ``ORTHOGONAL_EXTRA`` functions of the basis to fit against (the
accuracy this gives on FAUST is checked in tests/evaluation/test_two_curves.py)."""

import numpy as np
import pytest

from curvefm.pointwise import room_for_steps
from curvefm.pointwise.conversion import ORTHOGONAL_EXTRA, STEPPED_FROM
from curvefm.spectral import Basis


def basis(k: int) -> Basis:
    return Basis(np.arange(k, dtype=float), np.zeros((4, k)), np.full(4, 0.25))


@pytest.mark.parametrize(
    ("map_size", "basis_size", "kept"),
    [(120, 120, 120 - ORTHOGONAL_EXTRA), (100, 120, 90), (50, 120, 50), (70, 70, 70), (80, 80, STEPPED_FROM)],
)
def test_only_maps_without_room_for_the_steps_are_cut_and_never_below_the_prior_size(map_size, basis_size, kept):
    rng = np.random.default_rng(0)
    C_forward, C_back = rng.normal(size=(map_size, map_size)), rng.normal(size=(map_size, map_size))
    forward, back = room_for_steps(C_forward, C_back, basis(basis_size))
    assert forward.shape == back.shape == (kept, kept)
    np.testing.assert_array_equal(forward, C_forward[:kept, :kept])
    np.testing.assert_array_equal(back, C_back[:kept, :kept])
