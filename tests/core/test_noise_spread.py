"""The spreads the agent reads its noise from: the pooled estimate is sharp
and unbiased under random noise, stands aside where rounding shows, and
wild outputs do not move it."""
import numpy as np
import pytest

from sensorispace_ros.core.naive.noise import measure_noise
from sensorispace_ros.core.naive.noise_spread import (across_range_sd, clipped_variance,
                                                      ladder_steps, noise_rows, random_noise)

from imperfect_bodies import ImperfectSensing, SmoothBody

CENTER = np.array([0.3, -0.7])
TRIALS = 200


def _estimates(**imperfections) -> np.ndarray:
    return np.array([measure_noise(ImperfectSensing(SmoothBody(), seed=s, **imperfections),
                                   CENTER).sd for s in range(TRIALS)])


def _sensed(seed: int, **imperfections):
    body = ImperfectSensing(SmoothBody(), seed=seed, **imperfections)
    sensed = np.asarray(body.sense(noise_rows(CENTER, 16, 16)))
    return sensed[:16], sensed[16:].reshape(len(ladder_steps()), 16, -1)


def test_gaussian_noise_is_measured_without_bias_and_sharply():
    # Six receptors, 16 repeats and 14 second differences a line: the larger
    # of the two robust spreads read 6 % high, and one run in 20 by 20 % or more.
    ratio = _estimates(noise=1e-3) / 1e-3
    assert abs(ratio.mean() - 1.0) < 0.02
    assert np.percentile(np.abs(ratio - 1.0), 95) < 0.15


def test_heavy_tailed_noise_is_measured_near_its_sd():
    # Laplace noise of scale b has sd b * sqrt(2); the median absolute
    # deviation reads it 11 % low.
    ratio = _estimates(laplace=1e-3) / (1e-3 * np.sqrt(2.0))
    assert abs(ratio.mean() - 1.0) < 0.06


def test_repeats_and_lines_of_one_random_noise_are_pooled():
    pooled = [random_noise(*_sensed(s, noise=1e-4)) for s in range(20)]
    assert all(p is not None for p in pooled)
    for sd, repeat_sd, ladder_sd in pooled:
        assert min(repeat_sd, ladder_sd) <= sd <= max(repeat_sd, ladder_sd)


def test_rounding_the_repeats_miss_is_not_pooled_away():
    # Noise 1e-5 under steps of 1e-3: the repeats barely spread, the lines
    # see the rounding (sd 2.9e-4); the larger spread must stand.
    assert all(random_noise(*_sensed(s, noise=1e-5, quantum=1e-3)) is None for s in range(10))
    estimate = measure_noise(ImperfectSensing(SmoothBody(), seed=0, noise=1e-5, quantum=1e-3),
                             CENTER)
    assert estimate.sd >= 1e-3 / np.sqrt(12.0) / 2


def test_noiseless_and_exactly_repeating_outputs_are_not_pooled():
    assert random_noise(*_sensed(0)) is None
    assert random_noise(*_sensed(0, float32=True)) is None


def test_wild_values_do_not_move_the_clipped_variance():
    rng = np.random.default_rng(1)
    values = rng.normal(0.0, 1.0, (16, 6))
    clean, dof = clipped_variance(values, centred=True)
    values[3, 2], values[9, 4] = 1e3, -1e6
    wild, _ = clipped_variance(values, centred=True)
    assert dof == pytest.approx(6 * 15)
    assert wild == pytest.approx(clean, rel=0.1)
    assert np.isfinite(wild)


def test_a_lost_row_is_left_out():
    repeats, lines = _sensed(2, noise=1e-4)
    repeats[5] = np.nan
    lines[0, 7] = np.nan
    sd = random_noise(repeats, lines)
    assert sd is not None and np.isfinite(sd[0]) and 5e-5 < sd[0] < 2e-4


def test_the_spread_across_the_jacobians_range_is_the_receptors_alone():
    # Six states, ten receptors, rank 3: each repeat errs by J delta (a
    # joint's error, 100 times the receptors') plus receptor noise 1e-3.
    rng = np.random.default_rng(5)
    jac = rng.normal(size=(6, 10, 3)) @ rng.normal(size=(6, 3, 4))
    joints = np.einsum("bsm,brm->brs", jac, rng.normal(0.0, 0.1, (6, 16, 4)))
    receptors = rng.normal(0.0, 1e-3, joints.shape)
    assert across_range_sd(joints, jac, 3) < 1e-12
    noisy = 0.5 + joints + receptors
    noisy[2, 5] = np.nan                                # a lost row is left out
    jac[4] = 0.0                                        # so is a state without a Jacobian
    assert across_range_sd(noisy, jac, 3) == pytest.approx(1e-3, rel=0.1)
    assert across_range_sd(noisy[:, :1], jac, 3) == 0.0  # one repeat shows no spread
    assert across_range_sd(noisy, jac, 10) == 0.0       # nothing outside the range


def test_heavy_tailed_noise_is_never_taken_for_rounding():
    # The median absolute deviation reads Laplace repeats ~0.7 of their sd;
    # where the F test sends the estimate to the larger spread, one draw in
    # a hundred fell below half of it, the mark of repeats that do not
    # spread, and the agent stopped averaging. Rounding still reads as such.
    def ratios(**imperfections):
        noises = [measure_noise(ImperfectSensing(SmoothBody(), seed=s, **imperfections), CENTER)
                  for s in range(1000)]
        return np.array([n.repeat_sd / n.sd for n in noises])

    assert ratios(laplace=7e-4).min() >= 0.5
    assert ratios(quantum=1e-3).max() == 0.0
