"""The landmark prior in its child process: the same maps as in this process, each basis sent once, a cancel that
stops the child at its next step, a child that comes back after it was killed, and the child's lower priority."""

import os
import signal

import numpy as np
import pytest
from shapes import basis_of, ellipsoid

from curvefm.fmap import landmark_maps
from curvefm.fmap.landmark_prior import NoLongerWanted
from curvefm.session import PriorProcess, PriorUnavailable
from curvefm.session.prior_process import PRIOR_NICE

LANDMARKS = np.array([(0, 600), (100, 900), (250, 1100), (40, 700)])


@pytest.fixture(scope="module")
def bases():
    return basis_of(ellipsoid(), 40), basis_of(ellipsoid(radii=(1.1, 0.6, 0.55)), 40)


@pytest.fixture
def prior_process():
    process = PriorProcess()
    yield process
    process.close()


def test_the_child_computes_the_maps_this_process_would(bases, prior_process):
    expected = landmark_maps(*bases, LANDMARKS)
    maps = prior_process.landmark_maps(*bases, LANDMARKS)
    assert np.allclose(maps.C_MN, expected.C_MN, rtol=0, atol=1e-10)
    assert np.allclose(maps.C_NM, expected.C_NM, rtol=0, atol=1e-10)
    fewer = prior_process.landmark_maps(*bases, LANDMARKS[:3])
    assert np.allclose(fewer.C_MN, landmark_maps(*bases, LANDMARKS[:3]).C_MN, rtol=0, atol=1e-10)
    assert prior_process.bases_sent == 2  # both bases once, kept by the child for the second request


def test_a_cancel_stops_the_child_at_its_next_step(prior_process):
    # a bigger pair with many landmarks, so that the child is still at work when the parent's first poll cancels
    big = basis_of(ellipsoid(60, 120), 60), basis_of(ellipsoid(60, 120, radii=(1.1, 0.6, 0.55)), 60)
    landmarks = np.stack([np.arange(0, 7000, 250)] * 2, axis=1)
    prior_process.landmark_maps(*big, landmarks[:1])  # the child has the bases now
    asked = []
    with pytest.raises(NoLongerWanted):
        prior_process.landmark_maps(*big, landmarks, wanted=lambda: asked.append(1) or False)
    assert len(asked) == 1  # asked once, at the first poll; then the parent waited for the child to give up
    maps = prior_process.landmark_maps(*big, landmarks[:3])  # the child serves the next request
    assert np.allclose(maps.C_MN, landmark_maps(*big, landmarks[:3]).C_MN, rtol=0, atol=1e-10)


def test_a_killed_child_is_reported_and_started_again(bases, prior_process):
    prior_process.landmark_maps(*bases, LANDMARKS)
    first = prior_process.pid
    os.kill(first, signal.SIGKILL)
    with pytest.raises(PriorUnavailable, match="landmark prior's process"):
        prior_process.landmark_maps(*bases, LANDMARKS[:2])
    maps = prior_process.landmark_maps(*bases, LANDMARKS[:2])
    assert prior_process.pid not in (None, first)
    assert np.allclose(maps.C_MN, landmark_maps(*bases, LANDMARKS[:2]).C_MN, rtol=0, atol=1e-10)


def test_the_child_runs_at_a_lower_priority_on_every_thread(bases, prior_process):
    prior_process.landmark_maps(*bases, LANDMARKS[:1])
    own = os.getpriority(os.PRIO_PROCESS, 0)
    threads = os.listdir(f"/proc/{prior_process.pid}/task")
    assert {os.getpriority(os.PRIO_PROCESS, int(t)) for t in threads} == {min(19, own + PRIOR_NICE)}
