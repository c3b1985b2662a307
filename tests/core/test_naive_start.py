"""The naive agent's start (core.naive.start): a degenerate start (a straight
two-link arm, singular) is left for a state of the rank measured elsewhere,
seeded; a start whose probes agree is kept without a single extra sense call."""
import ast
from pathlib import Path

import numpy as np
import pytest

from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.start import point_ranks

START = Path(__file__).resolve().parents[2] / "sensorispace_ros" / "core" / "naive" / "start.py"
LIGHTS = np.array([[4.0, 1.0], [-3.0, 5.0], [1.0, -6.0]])


class TwoLinkArm:
    """Three receptors at the tip of a two-link arm (links of 2.5, radians),
    each summing 1 / (1 + d^2) over fixed lights: the sensation pins the tip."""

    n_motors, n_sensors = 2, 3

    def __init__(self):
        self.calls = 0

    def tip(self, motor):
        motor = np.atleast_2d(motor)
        first, second = motor[:, 0], motor[:, 0] + motor[:, 1]
        return 2.5 * np.column_stack([np.cos(first) + np.cos(second),
                                      np.sin(first) + np.sin(second)])

    def sense(self, motor):
        self.calls += 1
        receptors = self.tip(motor)[:, None, :] + np.array([[0, 0], [0.5, 0], [0, 0.5]])
        squared = ((receptors[:, :, None, :] - LIGHTS) ** 2).sum(axis=-1)
        return (1.0 / (1.0 + squared)).sum(axis=-1)


def started(start, seed=0):
    body = TwoLinkArm()
    agent = NaiveAgent(body, NaiveParams())
    reaction = agent.start(np.asarray(start, float), seed=seed)
    return agent, reaction, body


def test_a_straight_arm_moves_to_a_state_of_full_measured_rank():
    agent, reaction, body = started([0.0, 0.0])
    choice = agent.start_choice
    assert choice.moved and (choice.rank_at_start, choice.rank_elsewhere) == (1, 2)
    assert agent.structure.pose_rank == 2 and agent.structure.votes == agent.structure.probes
    rest = np.asarray(reaction.rest_motor_state)
    assert not np.allclose(rest, 0.0)
    # Not straight any more: the knee is bent, and the rank there is 2.
    assert abs(np.sin(rest[1])) > 0.05
    ranks, _ = point_ranks(body, rest[None], NaiveParams())
    assert ranks[0] == 2
    assert len(reaction.new_pov_ids) == 1 and "instead" in choice.describe()


def test_the_chosen_start_is_seeded():
    first = started([0.0, 0.0], seed=3)[1].rest_motor_state
    again = started([0.0, 0.0], seed=3)[1].rest_motor_state
    other = started([0.0, 0.0], seed=4)[1].rest_motor_state
    np.testing.assert_array_equal(first, again)
    assert not np.allclose(first, other)


def test_a_start_whose_probes_agree_is_kept_without_an_extra_sense_call():
    agent, reaction, _ = started([0.3, 1.2])
    assert agent.start_choice is None
    np.testing.assert_allclose(reaction.rest_motor_state, [0.3, 1.2])
    # The noise measurement's call and the structure's, nothing more.
    assert agent.calls_by_stage["rank"] == 2


def test_start_imports_nothing_of_the_world():
    imported = {node.module for node in ast.walk(ast.parse(START.read_text()))
                if isinstance(node, ast.ImportFrom)}
    assert imported <= {"__future__", "dataclasses", "sensorispace_ros.core.naive.structure",
                        "sensorispace_ros.core.seeding"}


@pytest.mark.parametrize("start", [[0.0, 0.0], [0.3, 1.2]])
def test_the_agent_state_keeps_its_start_choice(start):
    agent, _, _ = started(start)
    restored = NaiveAgent.from_state(TwoLinkArm(), agent.state())
    assert restored.start_choice == agent.start_choice
