"""The naive agent's tools under sensory noise: symmetric-difference
Jacobians, the chi-square acceptance of a compensation and matching by how
far a match stands out from the next sensation."""
from types import SimpleNamespace

import numpy as np
import pytest

from sensorispace_ros.core.naive.confirm import confirm_compensations, finite_mean
from sensorispace_ros.core.naive.equality_sets import match_sensations
from sensorispace_ros.core.naive.jacobians import (AveragedStep, SymmetricStep, jacobian_stencil,
    sensory_jacobian, stencil_bend, stencil_rows)

from imperfect_bodies import ImperfectSensing


class QuadraticBody:
    """Six outputs, quadratic in three joints: a known Jacobian anywhere."""

    n_motors, n_sensors = 3, 6
    A = np.array([[1.0, 0.2, 0.0], [0.0, 0.5, 0.1], [0.3, 0.0, 0.02],
                  [0.1, 0.1, 0.1], [0.0, 0.3, 0.01], [0.2, 0.0, 0.03]])
    B = 0.5 * np.arange(1, 7)

    def sense(self, motor_states):
        m = np.asarray(motor_states, dtype=float)
        return 0.4 + m @ self.A.T + self.B * np.sum(m ** 2, axis=1, keepdims=True)

    def jacobian(self, m):
        return self.A + 2.0 * self.B[:, None] * m[None, :]


class RankTwoBody:
    """Six outputs of a 2-D pose from three joints (pose = (m0 + m1, m2)):
    the compensations of a target form a line; its weakest pose direction
    moves the outputs ~30 times less than its strongest."""

    n_motors, n_sensors = 3, 6

    def sense(self, motor_states):
        m = np.asarray(motor_states, dtype=float)
        x, y = m[:, :1] + m[:, 1:2], m[:, 2:]
        k = np.arange(1, 7)
        return 0.5 + 0.3 * np.sin(k * x + k) + 0.01 * np.cos(k * y + 2 * k)


def test_a_symmetric_step_senses_both_sides_of_every_joint():
    states = np.array([[0.1, 0.2, 0.3]])
    stencil = jacobian_stencil(states, SymmetricStep(0.01))
    assert stencil_rows(3, SymmetricStep(0.01)) == 7 == len(stencil)
    offsets = np.round((stencil - states) / 0.01).astype(int)
    assert sorted(map(tuple, offsets[1:])) == sorted(
        map(tuple, np.vstack([np.eye(3), -np.eye(3)]).astype(int)))
    assert stencil_rows(3, 0.01) == 4


def test_symmetric_jacobian_of_a_quadratic_is_exact_where_forward_is_not():
    body, m = QuadraticBody(), np.array([0.2, -0.1, 0.4])
    _, central, rows = sensory_jacobian(body, m[None], SymmetricStep(0.05))
    _, forward, _ = sensory_jacobian(body, m[None], 0.05)
    true = body.jacobian(m)
    assert rows == 7
    assert np.max(np.abs(central[0] - true)) < 1e-12
    assert np.max(np.abs(forward[0] - true)) > 1e-2


def test_symmetric_jacobian_recovers_a_known_jacobian_under_noise():
    # Noise sd 1e-4: at step 0.05 the central estimate's entries spread by
    # sd / (sqrt(2) step) ~ 1.4e-3; the weakest column (0.02 .. 0.1) stands out.
    m = np.array([0.2, -0.1, 0.4])
    body = ImperfectSensing(QuadraticBody(), seed=5, noise=1e-4)
    _, jac, _ = sensory_jacobian(body, np.repeat(m[None], 200, axis=0), SymmetricStep(0.05))
    error = jac - QuadraticBody().jacobian(m)
    assert abs(np.std(error) - 1e-4 / (np.sqrt(2) * 0.05)) < 3e-4
    assert np.max(np.abs(error.mean(axis=0))) < 5e-4


def _confirm(body, states, target, target_sd, repeats=64):
    return confirm_compensations(body, states, np.repeat(target[None], len(states), axis=0),
                                 np.full(len(states), target_sd ** 2), noise_sd=1e-4,
                                 repeats=repeats, rank=2, fd_step=SymmetricStep(0.02),
                                 confidence=0.999)


def test_acceptance_keeps_a_compensation_on_the_targets_level_set_under_noise():
    rng = np.random.default_rng(0)
    exact = RankTwoBody()
    body = ImperfectSensing(exact, seed=1, noise=1e-4)
    target_state = np.array([0.3, 0.2, -0.4])
    target = finite_mean(body.sense(np.repeat(target_state[None], 64, axis=0)))
    # Along the level set (m0 + m1 fixed), a few noise-sized steps off it.
    states = target_state + np.array([1.0, -1.0, 0.0]) * rng.uniform(-1, 1, (40, 1))
    states += rng.normal(0.0, 1e-4, states.shape)
    stepped, accepted, _ = _confirm(body, states, target, 1e-4 / 8)
    assert accepted.mean() >= 0.95
    # The Gauss-Newton step brings the weak coordinate back to the target's.
    assert np.max(np.abs(stepped[accepted, 2] - target_state[2])) < 0.05


class Shifted:
    """``body`` whose outputs are all moved by ``offset``: the same pose in
    an environment that changed (a redistribution) senses something else."""

    n_motors, n_sensors = 3, 6

    def __init__(self, body, offset):
        self.body, self.offset = body, offset

    def sense(self, motor_states):
        return self.body.sense(motor_states) + self.offset


def test_acceptance_rejects_a_wrong_pose_whose_single_sensing_would_pass():
    # The state senses its target moved by 4e-4 in a direction no pose
    # change explains: within what one sensing of the target and one of
    # the state differ by (noise 1e-4, 6 outputs: ~6.7e-4 at 0.999), far
    # outside what averages of 64 do.
    exact = RankTwoBody()
    target_state = np.array([0.3, 0.2, -0.4])
    h = 1e-6
    jac = np.stack([(exact.sense((target_state + h * e)[None])
                     - exact.sense((target_state - h * e)[None]))[0] / (2 * h)
                    for e in np.eye(3)], axis=1)
    u = np.linalg.svd(jac)[0]
    offset = 4e-4 * u[:, 3]
    target = finite_mean(ImperfectSensing(exact, seed=2, noise=1e-4).sense(
        np.repeat(target_state[None], 64, axis=0)))
    assert np.linalg.norm(offset) < 1e-4 * np.sqrt(2 * 22.46)
    body = ImperfectSensing(Shifted(exact, offset), seed=4, noise=1e-4)
    _, accepted, _ = _confirm(body, np.repeat(target_state[None], 20, axis=0), target,
                              1e-4 / 8)
    assert not accepted.any()
    # The same states in the target's environment pass.
    _, accepted, _ = _confirm(ImperfectSensing(exact, seed=4, noise=1e-4),
                              np.repeat(target_state[None], 20, axis=0), target, 1e-4 / 8)
    assert accepted.mean() >= 0.9


def test_a_lost_row_never_confirms():
    body = ImperfectSensing(RankTwoBody(), seed=3, dropout=1.0)
    _, accepted, mean = _confirm(body, np.zeros((2, 3)), np.full(6, 0.5), 1e-4, repeats=4)
    assert not accepted.any() and np.all(np.isnan(mean))


def test_the_ratio_test_tells_a_match_from_a_near_neighbour():
    reference = np.array([[0.0, 0.0], [5.0, 5.0]])
    current = np.array([[0.01, 0.0], [0.025, 0.0], [5.01, 5.0], [6.0, 5.0]])
    # A wide tolerance: both rows have a candidate; the first's next
    # neighbour is within 3 x its distance, the second's is not.
    before, after = match_sensations(reference, current, match_tol=0.5, separation=1e-3,
                                     ratio=3.0)
    assert before.tolist() == [1] and after.tolist() == [2]
    # Without the ratio the separation alone (wider than the tolerance) decides.
    before, _ = match_sensations(reference, current, match_tol=0.5, separation=2.0)
    assert before.tolist() == []


def _structure(noise, repeat_noise, fd_step=1e-3, weakest=0.01):
    from sensorispace_ros.core.naive.structure import BodyStructure
    return BodyStructure(n_motors=4, pose_rank=3, rank_gap=10.0, gain=0.8, floor=0.0, votes=8,
                         probes=8, noise=noise, fd_step=fd_step, weakest=weakest,
                         repeat_noise=repeat_noise)


def test_averaging_pays_only_for_noise_that_repeats_do_not_repeat():
    from sensorispace_ros.core.naive.noise import averaging_repeats
    from sensorispace_ros.core.naive.params import NaiveParams
    params = NaiveParams(accept_repeats=16)
    assert averaging_repeats(params, _structure(1e-4, 1e-4)) == 16
    # Rounding: the repeats agree exactly, the ladder sees the rounding.
    assert averaging_repeats(params, _structure(1e-4, 0.0)) == 1
    assert averaging_repeats(params, _structure(0.0, 0.0)) == 1


def test_the_step_turns_symmetric_only_where_noise_reaches_the_weakest_direction():
    from sensorispace_ros.core.naive.noise import finite_difference_step, jacobian_noise
    from sensorispace_ros.core.naive.params import NaiveParams
    params = NaiveParams(fd_step=1e-3)
    quiet = _structure(1e-9, 1e-9)
    assert not isinstance(finite_difference_step(params, quiet, 6), SymmetricStep)
    loud = _structure(1e-4, 1e-4)
    step = finite_difference_step(params, loud, 6)
    assert isinstance(step, SymmetricStep) and step > 1e-3
    # Its Jacobian's noise is below the forward step's.
    assert jacobian_noise(loud, 6, step) < jacobian_noise(loud, 6, 1e-3)


def test_a_state_off_its_target_along_the_weak_direction_is_moved_there_or_rejected():
    # The weak pose coordinate (m2) 0.005 off: its residual lies in the
    # Jacobian's range, which a test of the residual outside it cannot see.
    # The rounds step it back; one round, which must accept or reject as it
    # stands, rejects it.
    exact = RankTwoBody()
    target_state = np.array([0.3, 0.2, -0.4])
    body = ImperfectSensing(exact, seed=6, noise=1e-4)
    target = finite_mean(body.sense(np.repeat(target_state[None], 64, axis=0)))
    states = np.repeat((target_state + [0.0, 0.0, 0.005])[None], 20, axis=0)
    stepped, accepted, _ = _confirm(body, states, target, 1e-4 / 8)
    assert accepted.mean() >= 0.9
    assert np.max(np.abs(stepped[accepted, 2] - target_state[2])) < 0.002
    _, once, _ = confirm_compensations(
        body, states, np.repeat(target[None], len(states), axis=0),
        np.full(len(states), (1e-4 / 8) ** 2), noise_sd=1e-4, repeats=64, rank=2,
        fd_step=SymmetricStep(0.02), confidence=0.999, rounds=1)
    assert not once.any()


def test_a_pose_the_noise_does_not_pin_is_rejected():
    # Target sensed once at noise 1e-4: the weak coordinate (gain ~0.01 per
    # output) is known to ~1e-2; held to 1e-3 nothing passes, to 1 all do.
    exact = RankTwoBody()
    target_state = np.array([0.3, 0.2, -0.4])
    body = ImperfectSensing(exact, seed=8, noise=1e-4)
    target = body.sense(target_state[None])[0]
    states = np.repeat(target_state[None], 10, axis=0)
    for max_error, passing in ((1e-3, 0.0), (1.0, 0.9)):
        _, accepted, _ = confirm_compensations(
            body, states, np.repeat(target[None], 10, axis=0), np.full(10, 1e-8),
            noise_sd=1e-4, repeats=16, rank=2, fd_step=SymmetricStep(0.02),
            confidence=0.999, max_error=max_error)
        assert (accepted.mean() >= passing) if passing else not accepted.any()


class BlankBody:
    """Six outputs that no joint moves: an eye that sees no light."""

    n_motors, n_sensors = 3, 6

    def sense(self, motor_states):
        return np.full((len(motor_states), 6), 0.1)


def test_a_pose_whose_sensation_does_not_follow_every_direction_is_rejected():
    # Where the eye sees nothing, any pose senses the target (the residual is
    # noise in and out of range); only the Jacobian's weakest direction
    # against the noise of the Jacobian (noise.jacobian_noise) tells.
    step = SymmetricStep(0.02)
    floor = 1e-4 * np.sqrt(2.0) * (np.sqrt(6) + np.sqrt(3)) / (2 * 0.02)
    states = np.repeat(np.array([0.3, 0.2, -0.4])[None], 10, axis=0)
    for body, minimum, passing in ((BlankBody(), 0.0, True), (BlankBody(), floor, False),
                                   (RankTwoBody(), floor, True)):
        accepted = _confirmed(ImperfectSensing(body, seed=9, noise=1e-4), states, step, minimum)
        assert (accepted.mean() >= 0.9) if passing else not accepted.any()


def _confirmed(noisy, states, step, minimum):
    """``confirm_compensations``' verdicts on ``states`` (10 alike) toward
    their first state's sensation averaged 64 times, at noise 1e-4."""
    target = finite_mean(noisy.sense(np.repeat(states[:1], 64, axis=0)))
    _, accepted, _ = confirm_compensations(
        noisy, states, np.repeat(target[None], 10, axis=0), np.full(10, 1e-8 / 64),
        noise_sd=1e-4, repeats=64, rank=2, fd_step=step, confidence=0.999,
        min_singular=minimum)
    return accepted


class BentBody(RankTwoBody):
    """``RankTwoBody`` whose weak coordinate ``y = m2`` enters only as
    ``y^3``: at ``y = 0`` no output follows it (the eye of one light in
    view), yet a central difference over ``+-h`` sees the outputs bend by
    ``~3 k h^2 / 2``."""

    def sense(self, motor_states):
        m = np.asarray(motor_states, dtype=float)
        k = np.arange(1, 7)
        return 0.5 + 0.3 * np.sin(k * (m[:, :1] + m[:, 1:2]) + k) + 1.5 * k * m[:, 2:] ** 3


def test_a_bend_above_the_agents_floor_falls_at_half_the_step():
    # Averaged 16 times a row, the bend stands 12 times above the agent's
    # floor (twice the noise's norm: receptor noise); at half the step it
    # falls to a quarter, a true direction's slope stays. Without a floor
    # nothing refuses it.
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.naive.searching import SearchAndSample

    step = AveragedStep(0.05, 16)
    agent = SimpleNamespace(params=NaiveParams(), _repeats=64, _fd_step=step,
                            structure=SimpleNamespace(noise=1e-4, receptor_noise=1e-4,
                                                      n_motors=3),
                            _body=SimpleNamespace(n_sensors=6))
    floor = SearchAndSample._pinning_floor(agent)
    states = np.repeat(np.array([0.3, 0.2, 0.0])[None], 10, axis=0)
    for body, minimum, passing in ((BentBody(), 0.0, True), (BentBody(), floor, False),
                                   (RankTwoBody(), floor, True)):
        noisy = ImperfectSensing(body, seed=11, noise=1e-4)
        _, jac = sensory_jacobian(noisy, states, step)[:2]
        assert np.all(np.linalg.svd(jac, compute_uv=False)[:, 1] > 4 * floor)
        accepted = _confirmed(noisy, states, step, minimum)
        assert (accepted.mean() >= 0.9) if passing else not accepted.any()


def test_matched_rows_pool_the_sensings_of_their_chain():
    from sensorispace_ros.core.naive.anchors import Snapshot, pooled_sweep
    old = Snapshot(0, np.array([[1.0, 1.0], [2.0, 2.0]]), np.ones(2, int), np.zeros(2),
                   np.zeros(3), -1, counts=np.array([3, 1]))
    current = np.array([[5.0, 5.0], [1.4, 1.4], [9.0, 9.0]])
    # Row 1 now senses what row 0 sensed (3 sensings pooled); row 2 matched nothing.
    pooled, counts = pooled_sweep([old], [(np.array([0]), np.array([1]))], current, cap=64)
    assert counts.tolist() == [1, 4, 1]
    assert np.allclose(pooled[1], (1.4 + 3 * 1.0) / 4) and np.allclose(pooled[[0, 2]],
                                                                        current[[0, 2]])
    _, capped = pooled_sweep([old], [(np.array([0]), np.array([1]))], current, cap=2)
    assert capped[1] == 2
    # A snapshot that pools nothing (a noiseless agent's) leaves the sweep as sensed.
    plain = Snapshot(0, old.sensations, old.rank, np.zeros(2), np.zeros(3), -1)
    pooled, counts = pooled_sweep([plain], [(np.array([0]), np.array([1]))], current, cap=64)
    assert np.array_equal(pooled, current) and counts.tolist() == [1, 1, 1]


def test_the_separation_of_povs_is_the_distance_between_neighbouring_loops():
    from sensorispace_ros.core.naive.points_of_view import PovStore
    store = PovStore(50, 2)
    angle = np.linspace(0.0, 2 * np.pi, 50, endpoint=False)
    for k in range(6):              # loops along joint 1 at joint 0 = 0.3 k (+- 2 pi)
        store.append(np.stack([np.full(50, 0.3 * k + 2 * np.pi * (k % 2)), angle], axis=1))
    assert store.separation() == pytest.approx(0.3)


def test_a_repaired_row_whose_sensation_is_lost_keeps_its_state_and_fails():
    """repair_rows: Gauss-Newton on rows of a linear body; one row's sensing is
    lost (NaN) every time. The others reach their targets; the lost one keeps
    its state, is reported as not repaired, and no non-finite motor state is
    ever sensed."""
    from sensorispace_ros.core.naive.jacobians import repair_rows

    gain = np.array([[1.0, 0.0], [0.0, 2.0], [1.0, 1.0]])
    asked = []

    class LinearBody:
        def sense(self, motor_states):
            motor_states = np.asarray(motor_states, dtype=float)
            asked.append(motor_states.copy())
            out = motor_states @ gain.T
            out[np.abs(motor_states[:, 0] - 0.5) < 0.2] = np.nan   # the lost row's region
            return out

    flat = np.array([[0.0, 0.0], [0.5, 0.5], [1.0, -1.0]])
    before = flat.copy()
    target = np.array([[0.1, 0.2], [0.6, 0.4], [0.9, -0.8]]) @ gain.T
    calls, sensed, failed = repair_rows(LinearBody(), flat, target, np.arange(3), rank=2,
                                        fd_step=1e-6, tol=1e-9, rounds=3)
    assert list(failed) == [1]
    np.testing.assert_array_equal(flat[1], before[1])
    np.testing.assert_allclose(flat[[0, 2]], [[0.1, 0.2], [0.9, -0.8]], atol=1e-6)
    assert all(np.isfinite(rows).all() for rows in asked)
    assert calls == len(sensed) and 1 in sensed[0]


class StepBody:
    """Six outputs linear in three joints, the first output jumping by 1 where
    the first joint passes 0.03."""

    n_motors, n_sensors = 3, 6

    def sense(self, motor_states):
        m = np.asarray(motor_states, dtype=float)
        out = 0.4 + m @ QuadraticBody.A.T
        out[:, 0] += (m[:, 0] > 0.03)
        return out


@pytest.mark.parametrize("step", [SymmetricStep(0.05), AveragedStep(0.05, 3)],
                         ids=["symmetric", "averaged"])
def test_a_stencil_bends_across_a_jump_and_runs_straight_elsewhere(step):
    states = np.array([[0.0, 0.0, 0.0], [-0.2, 0.1, 0.0]])

    def bend(body):
        answer = np.asarray(body.sense(jacobian_stencil(states, step)))
        return stencil_bend(answer.reshape(len(states), stencil_rows(3, step), -1), step)

    # Across the jump one side does not change along the first joint's
    # output: the bend nears 1; a linear body runs straight, a quadratic one
    # bends by its curvature alone.
    assert bend(StepBody())[0] > 0.8
    assert bend(StepBody())[1] < 1e-9
    assert np.all(bend(QuadraticBody()) < 0.5)


def test_a_forward_stencil_has_no_side_to_bend():
    answer = np.asarray(StepBody().sense(jacobian_stencil(np.zeros((1, 3)), 0.05)))
    assert stencil_bend(answer.reshape(1, 4, -1), 0.05).tolist() == [0.0]
