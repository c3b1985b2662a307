"""Naive POVs: walked through ``sense`` only, checked against the analytic walk."""
import functools
import types
import warnings

import numpy as np
import pytest

from sensorispace_ros.core import arm, retina
from sensorispace_ros.core.body import SimulatedBody
from sensorispace_ros.core.paper.exploration import build_world
from sensorispace_ros.core.hausdorff import hausdorff_pair
from sensorispace_ros.core.paper.points_of_view import (loop_winding, resample_closed_path,
    sample_points_of_view)
from sensorispace_ros.core.arm import PAPER_ARM
from sensorispace_ros.core.naive import points_of_view
from sensorispace_ros.core.naive.points_of_view import (NOT_CLOSED, RANK_DEFICIENT, SPLIT, VALID,
    has_full_pose_rank, resample_loop_spline, sensory_jacobian)

# The paper arm's pose rank (ground truth; the agent measures it, structure.py).
sample_sensory_points_of_view = functools.partial(points_of_view.sample_sensory_points_of_view,
                                                  rank=PAPER_ARM.pose_rank)


@pytest.fixture(scope="module")
def world():
    return build_world(0)


def _body(world):
    return SimulatedBody(world.receptors, world.initial_lights)


def _states_in_view(world, count, tip_min, tip_max, seed):
    """Motor states whose tip lies in [tip_min, tip_max] and that see >= 3 lights."""
    rng = np.random.default_rng(seed)
    found = []
    while len(found) < count:
        m = world.m0 + rng.normal(0.0, 0.8, 4)
        pose = arm.forward(m)
        if tip_min <= np.hypot(*pose[:2]) <= tip_max and \
                retina.lights_in_view(pose, world.initial_lights, world.receptors) >= 3:
            found.append(m)
    return np.asarray(found)


def closure_body(sense, n_motors=4, n_sensors=6):
    """A body with nothing to reach but ``sense`` and the two sizes."""
    return types.SimpleNamespace(sense=sense, n_motors=n_motors, n_sensors=n_sensors)


def test_naive_povs_match_the_analytic_walk_within_budget(world):
    starts = np.vstack([world.m0, _states_in_view(world, 2, 1.2, 2.8, seed=1)])
    sim = _body(world)
    body = closure_body(sim.sense)
    naive = sample_sensory_points_of_view(body, starts)
    analytic = sample_points_of_view(starts)
    assert naive.valid.all() and analytic.valid.all()
    for p in range(len(starts)):
        # The same start, samples equally spaced along the same loop: the two
        # sample sets agree pointwise, so their Hausdorff distance is tiny.
        assert hausdorff_pair(naive.samples[p], analytic.samples[p]) < 1e-4
    np.testing.assert_array_equal(naive.samples[:, 0], starts)
    poses = arm.forward(naive.samples)
    assert np.max(arm.pose_error(poses, arm.forward(starts)[:, None, :])) < 1e-6
    assert naive.queries.max() <= 5000
    # One sense call serves every walking POV: far fewer calls than steps.
    assert naive.calls < naive.steps.sum() / 2
    assert sim.queries == naive.queries.sum()


def _cyclic_chords(samples):
    return np.linalg.norm(np.diff(np.vstack([samples, samples[:1]]), axis=0), axis=1)


def test_fronts_meet_into_one_closed_loop_of_equal_arcs_on_the_level_set(world):
    starts = np.vstack([world.m0, _states_in_view(world, 3, 1.1, 2.9, seed=3)])
    sim = _body(world)
    result = sample_sensory_points_of_view(sim, starts)
    assert result.valid.all()
    for p in range(len(starts)):
        samples = result.samples[p]
        # Every sample senses what the start senses (on the POV) ...
        assert np.max(np.abs(sim.sense(samples) - sim.sense(starts[p:p + 1]))) < 1e-9
        # ... and the loop is traced once: N equal arcs, the last one (back
        # to the start, across where the two fronts met) included. Fronts
        # that passed each other, or stopped short, would leave one arc
        # longer or shorter than the others.
        chords = _cyclic_chords(samples)
        assert np.ptp(chords) < 1e-2 * np.median(chords)
        assert abs(chords[-1] - np.median(chords)) < 1e-3 * np.median(chords)


def test_two_fronts_and_probes_per_call_cut_the_sequential_calls(world):
    start = _states_in_view(world, 1, 1.1, 2.9, seed=4)
    one_probe = sample_sensory_points_of_view(_body(world), start, knots_per_step=1)
    four_probes = sample_sensory_points_of_view(_body(world), start, knots_per_step=4)
    assert one_probe.valid.all() and four_probes.valid.all()
    # The same loop, sampled the same way.
    assert hausdorff_pair(one_probe.samples[0], four_probes.samples[0]) < 1e-6
    assert four_probes.calls < one_probe.calls
    # A single front one knot per call, knots at most max_step = 0.15 apart,
    # needs at least (loop length) / max_step calls: both fronts with four
    # probes each need fewer than half of that.
    loop_length = _cyclic_chords(four_probes.samples[0]).sum()
    assert four_probes.calls < 0.5 * loop_length / 0.15


def test_split_points_of_view_are_rejected_like_the_paper(world):
    split_start = _states_in_view(world, 1, 0.3, 0.8, seed=2)
    # |tip| < 1: the fibre is two loops, each winding once around a joint
    # circle (paper Fig. 5b).
    assert np.hypot(*arm.forward(split_start[0])[:2]) < 1.0
    result = sample_sensory_points_of_view(_body(world), split_start)
    assert result.reason == [SPLIT] and not result.valid.any()


def test_blank_start_is_not_walked(world):
    # Every light far ahead along +x; an eye turned back (alpha = pi) sees none.
    lights = np.array([[9.0, -1.0], [10.0, 0.5], [11.0, 2.0]])
    body = SimulatedBody(world.receptors, lights)
    blank = np.array([0.0, 0.0, 0.0, np.pi])
    assert np.all(body.sense(blank[None]) == 0.0)
    result = sample_sensory_points_of_view(body, np.vstack([blank, world.m0]))
    assert result.reason[0] == RANK_DEFICIENT
    assert result.queries[0] == 5          # the start and its stencil, no walk


def test_a_front_at_a_blank_wall_neither_crosses_it_nor_poisons_the_walk(world):
    # The eye sees nothing once joint 0 exceeds the start by 0.3 rad: probes
    # beyond have a zero Jacobian and an infinite correction. The loop is cut,
    # so the walk cannot close; it must end at its budget without ever
    # commanding a non-finite motor state (a graph body drops such commands)
    # and without floating-point warnings.
    sim = _body(world)
    wall = world.m0[0] + 0.3
    commanded = []

    def sense(states):
        states = np.asarray(states, dtype=float)
        commanded.append(states)
        return np.where(states[:, :1] > wall, 0.0, sim.sense(states))

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = sample_sensory_points_of_view(closure_body(sense), world.m0[None],
                                               max_queries=2000)
    assert result.reason == [NOT_CLOSED]
    assert result.queries[0] <= 2000
    assert np.all(np.isfinite(np.concatenate(commanded)))


def test_walk_stops_at_the_query_budget(world):
    body = _body(world)
    result = sample_sensory_points_of_view(body, world.m0[None], max_queries=100)
    assert result.reason == [NOT_CLOSED]
    assert result.queries[0] <= 100


def test_spline_resampling_is_equally_spaced_where_chords_are_not():
    # A closed curve with known arc length: an ellipse in joints (0, 1),
    # traced by 60 unevenly spaced points (like the adaptive walk's).
    a, b = 1.0, 0.4
    t = np.sort(np.concatenate([[0.0], np.random.default_rng(0).uniform(0, 2 * np.pi, 59)]))
    path = np.stack([a * np.cos(t), b * np.sin(t), 0.3 + 0 * t, -0.2 + 0 * t], axis=1)
    fine = np.linspace(0.0, 2 * np.pi, 400_001)
    speed = np.hypot(a * np.sin(fine), b * np.cos(fine))
    arc = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(fine))])

    def arc_position(samples):
        angle = np.unwrap(np.arctan2(samples[:, 1] / b, samples[:, 0] / a)) % (2 * np.pi)
        return np.interp(angle, fine, arc)

    wanted = np.arange(100) * arc[-1] / 100
    spline = resample_loop_spline(path, 100)
    chords = resample_closed_path(path, 100)
    spline_error = np.max(np.abs(arc_position(spline) - wanted))
    chord_error = np.max(np.abs(arc_position(chords) - wanted))
    assert spline_error < 2e-4 < chord_error
    np.testing.assert_array_equal(spline[0], path[0])
    # Samples stay on the curve.
    assert np.max(np.abs((spline[:, 0] / a) ** 2 + (spline[:, 1] / b) ** 2 - 1)) < 1e-3


def test_resample_loop_spline_keeps_the_winding():
    t = np.linspace(0.0, 2 * np.pi, 40, endpoint=False)
    path = np.stack([t, np.sin(t), np.cos(t), 0 * t], axis=1)       # joint 0 turns once
    assert list(loop_winding(np.vstack([path, path[:1] + [2 * np.pi, 0, 0, 0]]))) == [1, 0, 0, 0]
    samples = resample_loop_spline(path, 50)
    assert np.all(np.diff(samples[:, 0]) > 0)
    assert samples[-1, 0] < 2 * np.pi


def test_sensory_jacobian_matches_the_chain_rule(world):
    body = _body(world)
    m = world.m0[None]
    _, jac, rows = sensory_jacobian(body, m, fd_step=1e-6)
    assert rows == 5 and body.calls == 1
    # d sense / dm = d sense / d pose (central differences) @ d pose / dm.
    pose = arm.forward(world.m0)
    d_pose = np.stack([(retina.sensation(pose + h, world.initial_lights, world.receptors)
                        - retina.sensation(pose - h, world.initial_lights, world.receptors))
                       / 2e-6 for h in 1e-6 * np.eye(3)], axis=1)
    np.testing.assert_allclose(jac[0], d_pose @ arm.jacobian(world.m0), atol=1e-4)
    assert has_full_pose_rank(jac, PAPER_ARM.pose_rank)[0]
    assert not has_full_pose_rank(np.zeros((1, 6, 4)), PAPER_ARM.pose_rank)[0]
    assert not has_full_pose_rank(jac, PAPER_ARM.pose_rank + 1)[0]   # the null direction


@pytest.mark.parametrize("name, value", [("initial_step", 0.0), ("predictor_tol", -1.0),
                                         ("n_samples", 1), ("max_queries", 0),
                                         ("min_step", np.nan), ("knots_per_step", 0)])
def test_bad_walk_parameters_are_named(world, name, value):
    with pytest.raises(ValueError, match=name):
        sample_sensory_points_of_view(_body(world), world.m0[None], **{name: value})


def test_bad_motor_states_are_rejected(world):
    with pytest.raises(ValueError, match="motor_states"):
        sample_sensory_points_of_view(_body(world), np.zeros((2, 3)))


def test_every_valid_reason_is_valid(world):
    result = sample_sensory_points_of_view(_body(world), world.m0[None])
    assert result.reason == [VALID] and result.valid.all()
