"""The bounded sweep of the agent on a clock (core/naive/clock_sweep.py): in
two calls, the second only when the first matched a snapshot."""
import types

import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.core.clocked_run import run_on_clock
from sensorispace_ros.core.naive.clock_sweep import BoundedSweep
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.run_world import run_world
from sensorispace_ros.evaluation.clock import clock_metrics
from sensorispace_ros.evaluation.naive import evaluate_naive_run


class _Body:
    n_sensors = 3

    def __init__(self):
        self.calls = []

    def sense(self, states):
        self.calls.append(np.asarray(states).copy())
        return np.asarray(states)[:, :3] + 1.0


class _Agent(BoundedSweep):
    """A stand-in with ``count`` known POVs, POV k's first sample all k."""

    def __init__(self, count, first, budget=8, rest=5, matched=False):
        self._store = types.SimpleNamespace(
            count=count, samples=np.repeat(np.arange(count, dtype=float)[:, None, None], 4,
                                           axis=2).repeat(2, axis=1))
        self._body, self._rest_pov, self.sweep_budget = _Body(), rest, budget
        self._sweep_cursor = 0
        self.params = types.SimpleNamespace(clock_sweep_first=first)
        self.matched, self.tested = matched, []

    def _match_snapshots(self, current, tree):
        self.tested.append(np.flatnonzero(np.all(np.isfinite(current), axis=1)))
        before = np.array([0]) if self.matched else np.zeros(0, int)
        return [(before, before)], np.array([-1]), None


def _sensed(agent):
    return [sorted(call[:, 0].astype(int)) for call in agent._body.calls]


def test_in_one_call_the_rest_and_the_budget():
    agent = _Agent(count=40, first=0)
    current, _ = agent._sweep_known()
    assert _sensed(agent) == [sorted(set(range(8)) | {5})]
    assert agent._sweep_cursor == 8 and not agent.tested
    assert np.all(np.isfinite(current[:8])) and np.all(np.isnan(current[8:]))


def test_a_first_part_that_matches_nothing_leaves_the_rest_for_the_next_sweep():
    agent = _Agent(count=40, first=3, rest=20)
    current, _ = agent._sweep_known()
    assert _sensed(agent) == [[0, 1, 2, 20]]
    np.testing.assert_array_equal(agent.tested[0], [0, 1, 2, 20])
    assert np.all(np.isnan(current[3:8]))
    # The next sweep begins with the POVs skipped.
    agent._sweep_known()
    assert _sensed(agent)[1] == [3, 4, 5, 20]


def test_a_first_part_that_matches_gets_the_rest_of_the_budget():
    agent = _Agent(count=40, first=3, rest=20, matched=True)
    current, _ = agent._sweep_known()
    assert _sensed(agent) == [[0, 1, 2, 20], [3, 4, 5, 6, 7]]
    assert np.all(np.isfinite(current[[0, 1, 2, 3, 4, 5, 6, 7, 20]]))
    assert agent._sweep_cursor == 8
    # Its witnesses come from both calls: the four that sensed most.
    np.testing.assert_array_equal(agent._witnesses[0][:, 0], [20, 7, 6, 5])


def test_the_rest_is_not_sensed_twice_and_few_povs_take_one_call():
    agent = _Agent(count=40, first=3, rest=1, matched=True)
    agent._sweep_known()
    assert _sensed(agent) == [[0, 1, 2, 3], [4, 5, 6, 7]]
    few = _Agent(count=9, first=3)
    few._sweep_known()
    assert _sensed(few) == [list(range(9))] and not few.tested


def test_clock_sweep_first_is_checked_at_start_up():
    with pytest.raises(config.ConfigError, match=r"naive\.clock_sweep_first"):
        config.load_config("config/smoke.yaml", {"naive.clock_sweep_first": -1})


def test_a_clocked_run_with_two_call_sweeps_accepts_nothing_across_a_change():
    runs = {}
    for first in (0, 4):
        cfg = config.load_config("config/smoke.yaml", {
            "world.clock": "rows", "world.change_interval": 1000.0,
            "naive.clock_sweep_budget": 8, "naive.clock_sweep_first": first})
        world = run_world(cfg)
        run = run_on_clock(world, NaiveParams(**cfg["naive"]), "rows", interval=1000.0)
        runs[first] = {**evaluate_naive_run(run, world).metrics, **clock_metrics(run, world)}
    two = runs[4]
    assert two["naive.accepted_across_change"] == 0 and two["naive.wrong_poses"] == 0
    assert two["naive.distinct_positions"] > 10
    # Sweeps that matched nothing stopped at their first part: fewer sweep rows a reaction.
    per_reaction = {f: m["naive.queries_by_stage.sweep"] / m["naive.clock.reactions"]
                    for f, m in runs.items()}
    assert per_reaction[4] < per_reaction[0]
