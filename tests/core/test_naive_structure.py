"""The naive agent's measure of its own body: pose rank, POV dimension, gain,
from ``sense`` alone, checked against the arm's ground truth outside it."""
import types
from pathlib import Path

import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.core.motor_loops import closure_gap_ratio
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.sense_memory import MotorPhase
from sensorispace_ros.core.naive.structure import (gap_rank, measure_structure,
    structure_from_probes)
from sensorispace_ros.core.run_world import run_world

BODIES = sorted((Path(__file__).resolve().parents[2] / "config" / "bodies").glob("*.yaml"))


def _world(path, seed=0):
    cfg = config.load_config(path)
    return run_world(cfg, seed)


def _phase_body(simulator, scale=1.0):
    """``simulator`` as the agent's counting body sees it: phases in, its
    sensations (times ``scale``) out."""
    phase = MotorPhase(simulator.description.periods)
    return types.SimpleNamespace(
        sense=lambda rows: scale * simulator.sense(phase.to_body(rows)),
        n_motors=simulator.n_motors, n_sensors=simulator.n_sensors), phase


@pytest.mark.parametrize("path", BODIES, ids=lambda p: p.stem)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_catalogue_body_gets_its_true_rank(path, seed):
    world = _world(path, seed)
    body, phase = _phase_body(world.body(lights=world.initial_lights))
    structure = measure_structure(body, phase.to_phase(world.m0), fd_step=1e-6)
    assert structure.pose_rank == world.arm.pose_rank
    assert structure.pov_dim == world.arm.pov_dim
    assert structure.votes == structure.probes
    assert structure.rank_gap > 1e4          # the cut is clear, decades wide


@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_the_estimate_does_not_depend_on_the_scale_of_the_sensations(scale):
    world = _world(BODIES[0].parent / "paper.yaml")
    simulator = world.body(lights=world.initial_lights)
    plain, phase = _phase_body(simulator)
    scaled, _ = _phase_body(simulator, scale)
    m0 = phase.to_phase(world.m0)
    a = measure_structure(plain, m0, fd_step=1e-6)
    b = measure_structure(scaled, m0, fd_step=1e-6)
    assert (a.pose_rank, a.votes) == (b.pose_rank, b.votes) == (3, 8)
    # Singular values and noise floor scale together; only rounding differs.
    assert b.rank_gap == pytest.approx(a.rank_gap, rel=0.2)
    assert b.gain == pytest.approx(scale * a.gain, rel=1e-6)


def _two_joint_body(level):
    """A body written as a bare closure: two joints, a sensation that sees
    only ``level(m)``: rank 1, so its POVs are the curves ``level = c``."""
    def sense(rows):
        value = level(np.asarray(rows, dtype=float))
        return np.stack([value, value ** 2, np.sin(value)], axis=1)

    return types.SimpleNamespace(sense=sense, n_motors=2, n_sensors=3)


def test_a_bare_closure_with_two_joints_and_a_rank_one_sensation():
    body = _two_joint_body(lambda m: np.cos(m[:, 0]) + np.cos(m[:, 1]))
    structure = measure_structure(body, np.array([0.3, -1.1]), fd_step=1e-6)
    assert (structure.pose_rank, structure.pov_dim) == (1, 1)
    agent = NaiveAgent(body, NaiveParams())
    reaction = agent.start([0.3, -1.1])
    assert (agent.structure.pose_rank, agent.structure.pov_dim) == (1, 1)
    # Its POV, cos m0 + cos m1 = c, is a closed loop round (0, 0): walked whole.
    assert len(reaction.new_pov_ids) == 1
    samples = reaction.new_povs[0]
    level = np.cos(0.3) + np.cos(-1.1)
    np.testing.assert_allclose(np.cos(samples).sum(axis=1), level, atol=1e-9)
    assert np.ptp(samples[:, 0]) > 1.0 and np.ptp(samples[:, 1]) > 1.0


def test_a_loop_that_closes_only_a_period_away_is_not_taken():
    # POVs m0 + m1 = c: lines that close in the torus only after a whole turn
    # of both joints; the agent cannot tell such a loop from one piece of a
    # POV made of several, so it keeps none of them.
    body = _two_joint_body(lambda m: np.cos(m[:, 0] + m[:, 1]) + 0.1 * np.sin(m[:, 0] + m[:, 1]))
    agent = NaiveAgent(body, NaiveParams())
    reaction = agent.start([0.3, -1.1])
    assert (agent.structure.pose_rank, agent.structure.pov_dim) == (1, 1)
    assert len(reaction.new_pov_ids) == 0
    np.testing.assert_array_equal(agent.split_motor_states, [[0.3, -1.1]])


def test_a_blank_body_votes_for_nothing():
    body = types.SimpleNamespace(sense=lambda m: np.zeros((len(m), 6)), n_motors=4, n_sensors=6)
    structure = measure_structure(body, np.zeros(4), fd_step=1e-6)
    assert structure.pose_rank == 0 and structure.votes == 0


def test_gap_rule_cuts_at_the_largest_ratio_and_counts_the_floor():
    singular = np.array([[1.0, 0.1, 1e-3, 1e-12],      # rank 3 (gap 1e-3 / floor)
                         [1.0, 0.5, 0.2, 0.1],          # full rank 4 against the floor
                         [1.0, 1e-9, 1e-12, 1e-12]])    # rank 1
    rank, gap = gap_rank(singular, np.full(3, 1e-10))
    assert list(rank) == [3, 4, 1]
    np.testing.assert_allclose(gap, [1e7, 1e9, 1e9])
    # Probes vote; a tie goes to the larger rank; a blank probe does not vote.
    votes = structure_from_probes(np.array([[1.0, 1e-2, 1e-12], [1.0, 1e-2, 1e-12],
                                            [1.0, 1e-12, 1e-12], [1e-12, 1e-12, 1e-12]]),
                                  np.full(4, 1e-10), n_motors=3, min_gap=100.0)
    assert (votes.pose_rank, votes.votes, votes.probes) == (2, 2, 4)


def test_phases_leave_radians_untouched_and_map_a_period_to_two_pi():
    rows = np.random.default_rng(0).normal(size=(5, 4))
    radians = MotorPhase([2 * np.pi] * 4)
    assert radians.to_phase(rows) is rows and radians.to_body(rows) is rows
    mixed = MotorPhase([360.0, 2 * np.pi, 1.0, 360.0])
    np.testing.assert_allclose(mixed.to_phase([[360.0, 1.0, 0.5, -90.0]]),
                               [[2 * np.pi, 1.0, np.pi, -np.pi / 2]])
    np.testing.assert_allclose(mixed.to_body(mixed.to_phase(rows)), rows, rtol=1e-15)


def test_closure_gap_ratio_tells_a_closed_loop_from_one_a_period_away():
    t = np.linspace(0.0, 2 * np.pi, 60, endpoint=False)
    closed = np.stack([np.cos(t), np.sin(t), 0 * t], axis=1)
    wound = np.stack([t, np.sin(t), np.cos(t)], axis=1)       # joint 0 turns once
    assert closure_gap_ratio(closed) < 0.05
    assert closure_gap_ratio(wound) > 0.5
