"""A world that changes while the agent senses its start state again and
again: the noise is measured from the repeats of the last world only."""
import numpy as np
import pytest

from sensorispace_ros.core.naive.noise import measure_noise
from sensorispace_ros.core.naive.repeat_step import last_world_start

SD = 1e-4
N_SENSORS = 6


@pytest.mark.parametrize("split", range(6, 11))
def test_a_change_among_the_repeats_is_found_where_it_fell(split):
    # Nearer either end the change leaves the repeats' robust spread nearly
    # as it is (test_the_noise_call_measures_the_last_world_it_saw).
    rng = np.random.default_rng(split)
    repeats = 0.4 + rng.normal(0.0, SD, (16, N_SENSORS))
    repeats[split:] += rng.uniform(-0.2, 0.2, N_SENSORS)
    assert last_world_start(repeats) == split


def test_noise_alone_shows_no_step():
    rng = np.random.default_rng(0)
    draws = [rng.normal(0.0, SD, (16, N_SENSORS)), rng.laplace(0.0, SD, (16, N_SENSORS)),
             SD * rng.standard_t(3, (16, N_SENSORS))]
    for _ in range(300):
        assert all(last_world_start(0.4 + noise) == 0 for noise in draws)
        draws = [rng.normal(0.0, SD, (16, N_SENSORS)), rng.laplace(0.0, SD, (16, N_SENSORS)),
                 SD * rng.standard_t(3, (16, N_SENSORS))]


def test_noiseless_repeats_lost_rows_and_lattices():
    rows = np.full((17, N_SENSORS), 0.4)
    assert last_world_start(rows) == 0
    rows[9:] += 0.1
    assert last_world_start(rows) == 0          # 9 rows before, 8 after: the median is the first's
    # A lost row counts for neither part (8 and 8: the median between the
    # two worlds); the split is a row of the input.
    rows[3] = np.nan
    assert last_world_start(rows) == 9
    # Noisy outputs on a lattice of step 1e-3: one step between the halves is not a change.
    rng = np.random.default_rng(4)
    lattice = np.round((0.4 + rng.normal(0.0, 4e-4, (16, N_SENSORS))) / 1e-3) * 1e-3
    lattice[8:] += 1e-3
    assert last_world_start(lattice, quantum=1e-3) == 0


class _ChangingBody:
    """Linear sensations of the motor state plus noise; after ``change``
    rows of its first call the world moves every output by ``jump``."""

    n_sensors = N_SENSORS

    def __init__(self, change: int, jump: np.ndarray, seed: int = 2):
        self.change, self.jump = change, jump
        self.rng = np.random.default_rng(seed)
        self.gain = self.rng.normal(0.0, 1.0, (4, N_SENSORS))

    def sense(self, motor_states):
        motor_states = np.asarray(motor_states, dtype=float)
        out = 0.4 + motor_states @ self.gain + self.rng.normal(0.0, SD, (len(motor_states),
                                                                         N_SENSORS))
        out[self.change:] += self.jump
        return out


@pytest.mark.parametrize("change", [4, 5, 8, 10])
def test_the_noise_call_measures_the_last_world_it_saw(change):
    jump = np.linspace(-0.2, 0.3, N_SENSORS)
    center = np.array([0.1, -0.2, 0.3, 0.0])
    still = measure_noise(_ChangingBody(10 ** 6, np.zeros(N_SENSORS)), center)
    changed = measure_noise(_ChangingBody(change, jump), center)
    # Without the step test the repeats' spread is the jump's (~0.1).
    assert changed.sd < 1.5 * still.sd < 3 * SD
    # The start state's sensation is the world's after the change.
    assert np.allclose(changed.center, 0.4 + center @ _ChangingBody(0, jump).gain + jump,
                       atol=5 * SD)
