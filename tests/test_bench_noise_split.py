"""bench/noise_split.py's split of a body's noise into its receptors' and its joints'."""
import sys

import numpy as np
import pytest

from shared import REPO
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests" / "core"))

from bench import noise_split  # noqa: E402
from imperfect_bodies import ImperfectSensing  # noqa: E402
from sensorispace_ros.core.naive.sense_memory import CountingBody  # noqa: E402

N_MOTORS, N_SENSORS, RANK = 4, 60, 3


class LowRankBody:
    """Smooth outputs of three combinations of four joints: a pose of rank 3."""

    n_motors, n_sensors = N_MOTORS, N_SENSORS

    def __init__(self):
        rng = np.random.default_rng(5)
        self.pose = rng.normal(size=(RANK, N_MOTORS))
        self.mix = rng.normal(size=(N_SENSORS, RANK))

    def sense(self, motor_states):
        pose = np.asarray(motor_states, dtype=float) @ self.pose.T
        return 0.5 + 0.2 * np.tanh(pose @ self.mix.T)


def _split(**imperfections):
    body = CountingBody(ImperfectSensing(LowRankBody(), seed=3, **imperfections))
    return noise_split.split_noise(body, np.full(N_MOTORS, 0.1), RANK, 0.05)


@pytest.mark.parametrize("receptors, joints", [(1e-4, 0.0), (0.0, 1e-3), (1e-4, 1e-3)])
def test_the_split_finds_each_kind_of_noise_at_its_size(receptors, joints):
    split = _split(noise=receptors, motor_noise=joints)
    if receptors:
        assert split["sd_across"] == pytest.approx(receptors, rel=0.15)
    else:
        assert split["sd_across"] < 0.1 * split["sd_all"]   # what the Jacobian's step bends
    if joints:
        assert split["motor_sd"] == pytest.approx(joints, rel=0.5)
        assert split["sd_across"] < 0.5 * split["sd_all"]    # the split is clear
    else:
        assert split["motor_sd"] < 0.3 * receptors / min(split["singular"])
        assert split["sd_across"] == pytest.approx(split["sd_all"], rel=0.15)
