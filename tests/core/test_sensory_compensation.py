"""Naive compensation: Levenberg-Marquardt on sensory error, with the rank test."""
import functools
import types

import numpy as np
import pytest

from sensorispace_ros.core import arm
from sensorispace_ros.core.body import SimulatedBody
from sensorispace_ros.core.paper.exploration import build_world
from sensorispace_ros.core.arm import PAPER_ARM
from sensorispace_ros.core.naive import compensation
from sensorispace_ros.core.world import draw_light_offsets


# The paper arm's pose rank (ground truth; the agent measures it, structure.py).
compensate = functools.partial(compensation.compensate, rank=PAPER_ARM.pose_rank)


@pytest.fixture(scope="module")
def world():
    return build_world(0)


def _target(world):
    body = SimulatedBody(world.receptors, world.initial_lights)
    return body.sense(world.m0[None])[0]


def test_translation_is_compensated_at_the_displaced_pose(world):
    target = _target(world)
    shift = np.array([-0.6, 0.4])
    sim = SimulatedBody(world.receptors, world.initial_lights + shift)
    body = types.SimpleNamespace(sense=sim.sense, n_motors=4, n_sensors=6)
    starts = np.vstack([world.m0, world.m0 + [0.3, -0.2, 0.1, 0.0]])
    result = compensate(body, np.repeat(target[None], 2, axis=0), starts)
    assert result.accepted.all()
    wanted = arm.forward(world.m0) + [*shift, 0.0]
    # The eye moved with the object: same relative pose, same sensation.
    assert np.max(arm.pose_error(arm.forward(result.motor_states), wanted)) < 1e-8
    assert np.all(result.sensory_error <= 1e-10)
    # One sense call per iteration carries every search and its stencil.
    assert result.calls == result.iterations.max() + 1
    assert sim.queries == result.queries.sum()


def test_out_of_reach_translation_and_redistribution_are_refused(world):
    target = _target(world)
    starts = np.vstack([world.m0, world.m0 + [0.5, 0.5, -0.5, 0.0], world.m0 + [-1.0, 0, 0, 0]])
    targets = np.repeat(target[None], len(starts), axis=0)
    pose0 = arm.forward(world.m0)
    shift = 4.0 * pose0[:2] / np.hypot(*pose0[:2])        # the sensor would need |tip| > 5
    far = SimulatedBody(world.receptors, world.initial_lights + shift)
    assert not compensate(far, targets, starts).accepted.any()
    rng = np.random.default_rng(5)
    for _ in range(3):
        lights = world.initial_center + draw_light_offsets(rng, len(world.initial_offsets))
        moved = SimulatedBody(world.receptors, lights)
        assert not compensate(moved, targets, starts).accepted.any()


def test_blank_target_is_refused_by_the_rank_test_alone(world):
    # Lights only far along +x: an eye turned back sees nothing, anywhere.
    lights = np.array([[9.0, -1.0], [10.0, 0.5], [11.0, 2.0]])
    body = SimulatedBody(world.receptors, lights)
    blank_target = np.zeros((1, 6))
    start = np.array([[0.3, 0.2, -0.4, np.pi]])
    assert np.all(body.sense(start) == 0.0)
    result = compensate(body, blank_target, start)
    # The error is exactly zero: only the rank test stands between a blank
    # sensation and a "compensation" anywhere.
    assert result.sensory_error[0] == 0.0
    assert result.rank_ratio[0] < 1e-3
    assert not result.accepted[0]


def test_searches_are_independent_in_a_batch(world):
    target = _target(world)
    shift = np.array([0.3, 0.3])
    body = SimulatedBody(world.receptors, world.initial_lights + shift)
    good = world.m0
    hopeless = np.array([0.0, 0.0, 0.0, world.m0.sum() + np.pi])     # eye turned away
    together = compensate(body, np.repeat(target[None], 2, axis=0), np.vstack([good, hopeless]))
    alone = compensate(body, target[None], good[None])
    assert together.accepted[0] and not together.accepted[1]
    np.testing.assert_allclose(together.motor_states[0], alone.motor_states[0], atol=1e-12)


def test_restarts_toward_a_found_target_stop(world):
    target = _target(world)
    shift = np.array([0.3, 0.3])
    body = SimulatedBody(world.receptors, world.initial_lights + shift)
    starts = np.vstack([world.m0, world.m0 + [0.6, -0.4, 0.3, -0.2],
                        world.m0 + [-0.8, 0.5, 0.4, -0.3]])
    targets = np.repeat(target[None], len(starts), axis=0)
    every = compensate(body, targets, starts, stop_found_targets=False)
    first = compensate(body, targets, starts)
    assert every.accepted.all()                 # each restart would find it ...
    assert first.accepted.any()                 # ... one is enough
    assert first.calls < every.calls
    found = first.motor_states[first.accepted]
    wanted = arm.forward(world.m0) + [*shift, 0.0]
    assert np.max(arm.pose_error(arm.forward(found), wanted)) < 1e-8
    # Another target's search goes on after this one is found (5 vs 9
    # iterations here), exactly as it would alone.
    near, far = world.m0, world.m0 + [0.3, -0.3, 0.2, 0.1]
    two_targets = body.sense(np.vstack([near, far]))
    two_starts = np.vstack([near + 0.01, far + [0.5, -0.5, 0.3, 0.2]])
    both = compensate(body, two_targets, two_starts)
    alone = compensate(body, two_targets[1:], two_starts[1:])
    assert both.accepted.all() and both.iterations[0] < both.iterations[1]
    assert both.iterations[1] == alone.iterations[0]
    np.testing.assert_array_equal(both.motor_states[1], alone.motor_states[0])


def test_restarts_in_turn_run_only_after_those_before_failed(world):
    target = _target(world)
    shift = np.array([0.3, 0.3])
    body = SimulatedBody(world.receptors, world.initial_lights + shift)
    starts = np.vstack([world.m0 + [0.6, -0.4, 0.3, -0.2], world.m0,
                        world.m0 + [-0.8, 0.5, 0.4, -0.3]])
    targets = np.repeat(target[None], len(starts), axis=0)
    together = compensate(body, targets, starts)
    in_turn = compensate(body, targets, starts, in_turn=True)
    assert in_turn.accepted.any() and in_turn.queries.sum() < together.queries.sum()
    # Only the start sensing most like the target searched past the first call.
    first_error = np.linalg.norm(body.sense(starts) - target, axis=1)
    assert np.flatnonzero(in_turn.iterations) == [np.argmin(first_error)]
    wanted = arm.forward(world.m0) + [*shift, 0.0]
    found = in_turn.motor_states[in_turn.accepted]
    assert np.max(arm.pose_error(arm.forward(found), wanted)) < 1e-8
    # Where every start fails, each runs in its turn, as long as it would at once.
    lights = world.initial_center + draw_light_offsets(np.random.default_rng(0),
                                                       len(world.initial_offsets))
    moved = SimulatedBody(world.receptors, lights)
    at_once = compensate(moved, targets, starts)
    turns = compensate(moved, targets, starts, in_turn=True)
    assert not turns.accepted.any()
    np.testing.assert_array_equal(turns.iterations, at_once.iterations)
    assert turns.calls > at_once.calls


def test_in_turn_senses_a_stencil_only_for_the_starts_it_searches(world):
    # Lights redistributed: every start fails. With one turn only the start
    # sensing most like the target searches, exactly as it would alone; the
    # others cost their own row, not their stencil.
    target = _target(world)
    lights = world.initial_center + draw_light_offsets(np.random.default_rng(0),
                                                       len(world.initial_offsets))
    sim = SimulatedBody(world.receptors, lights)
    sensed_rows = []
    body = types.SimpleNamespace(n_motors=4, n_sensors=6,
                                 sense=lambda m: sensed_rows.append(len(m)) or sim.sense(m))
    starts = np.vstack([world.m0 + [0.6, -0.4, 0.3, -0.2], world.m0,
                        world.m0 + [-0.8, 0.5, 0.4, -0.3]])
    targets = np.repeat(target[None], len(starts), axis=0)
    one = compensate(body, targets, starts, in_turn=True, max_turns=1)
    assert not one.accepted.any() and sum(sensed_rows) == one.queries.sum()
    best = int(np.argmin(np.linalg.norm(sim.sense(starts) - target, axis=1)))
    assert np.flatnonzero(one.iterations) == [best]
    assert np.all(one.queries[np.arange(3) != best] == 1)
    alone = compensate(sim, targets[best:best + 1], starts[best:best + 1], in_turn=True)
    np.testing.assert_array_equal(one.motor_states[best], alone.motor_states[0])
    assert one.iterations[best] == alone.iterations[0]
    assert one.queries[best] == alone.queries[0]


@pytest.mark.parametrize("in_turn", [False, True])
def test_trials_sensed_alone_first_take_the_same_steps_for_fewer_rows(world, in_turn):
    # Reachable targets from far starts and redistributed lights (every search
    # fails): a rejected trial costs one row instead of its stencil, and every
    # search takes the same states, iterations and verdict.
    target = _target(world)
    lights = world.initial_center + draw_light_offsets(np.random.default_rng(0),
                                                       len(world.initial_offsets))
    starts = world.m0 + np.random.default_rng(7).normal(0.0, 0.5, (8, 4))
    targets = np.repeat(target[None], len(starts), axis=0)
    rows = {"whole": 0, "first": 0}
    for lit in (world.initial_lights + [0.3, 0.3], lights):
        sim = SimulatedBody(world.receptors, lit)
        sensed_rows = []
        body = types.SimpleNamespace(n_motors=4, n_sensors=6,
                                     sense=lambda m: sensed_rows.append(len(m)) or sim.sense(m))
        whole = compensate(sim, targets, starts, in_turn=in_turn)
        first = compensate(body, targets, starts, in_turn=in_turn, probe_first=True)
        np.testing.assert_array_equal(first.motor_states, whole.motor_states)
        np.testing.assert_array_equal(first.iterations, whole.iterations)
        np.testing.assert_array_equal(first.accepted, whole.accepted)
        assert sum(sensed_rows) == first.queries.sum() <= whole.queries.sum()
        assert first.calls >= whole.calls
        rows["whole"] += whole.queries.sum()
        rows["first"] += first.queries.sum()
    assert rows["first"] < rows["whole"]


def test_a_trial_whose_stencil_loses_a_row_is_not_taken(world):
    # The trial senses better alone, then a row of its stencil comes back lost:
    # no Jacobian there, so the search stays where it was.
    target = _target(world)
    sim = SimulatedBody(world.receptors, world.initial_lights + [0.3, 0.3])
    calls = []

    def sense(m):
        calls.append(len(m))
        out = sim.sense(m)
        if len(calls) == 3:         # the first trial's stencil (after the start's, the trial's)
            out[-1] = np.nan
        return out

    body = types.SimpleNamespace(n_motors=4, n_sensors=6, sense=sense)
    start = world.m0[None] + 0.05
    lost = compensate(body, target[None], start, probe_first=True, max_iterations=1)
    np.testing.assert_array_equal(lost.motor_states, start)
    assert calls == [5, 1, 4] and lost.queries[0] == 10 and np.isfinite(lost.sensory_error[0])


def test_searches_at_a_local_minimum_stop_early_with_the_same_error(world):
    # Lights redistributed: the old sensation exists nowhere, the searches
    # end in local minima with a nonzero residual.
    target = _target(world)
    lights = world.initial_center + draw_light_offsets(np.random.default_rng(0),
                                                       len(world.initial_offsets))
    body = SimulatedBody(world.receptors, lights)
    starts = world.m0 + np.random.default_rng(7).normal(0.0, 0.5, (12, 4))
    targets = np.repeat(target[None], len(starts), axis=0)
    waiting = compensate(body, targets, starts, stall_iterations=4, stationary_ratio=0.0)
    stopping = compensate(body, targets, starts, stall_iterations=4)
    assert not waiting.accepted.any() and not stopping.accepted.any()
    earlier = stopping.iterations < waiting.iterations
    assert earlier.any() and stopping.calls < waiting.calls
    # The iterations saved would not have lowered the error by more than a few %.
    np.testing.assert_allclose(stopping.sensory_error[earlier], waiting.sensory_error[earlier],
                               rtol=0.05)


@pytest.mark.parametrize("name, value", [("error_tol", 0.0), ("max_iterations", 0),
                                         ("stall_factor", 1.0), ("rank_ratio", -1.0),
                                         ("stationary_ratio", 1.0)])
def test_bad_search_parameters_are_named(world, name, value):
    body = SimulatedBody(world.receptors, world.initial_lights)
    with pytest.raises(ValueError, match=name):
        compensate(body, np.zeros((1, 6)), world.m0[None], **{name: value})


def test_shapes_are_checked(world):
    body = SimulatedBody(world.receptors, world.initial_lights)
    with pytest.raises(ValueError, match="starts"):
        compensate(body, np.zeros((1, 6)), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="target_sensations"):
        compensate(body, np.zeros((2, 6)), world.m0[None])
