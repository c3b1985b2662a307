"""Frontier targets of many sensings: where one sensing of a sweep row
cannot pin its pose, a snapshot averages some of its rows before the
environment changes, and frontier requests take the rows of most
sensings first."""
from contextlib import contextmanager
from types import SimpleNamespace

import numpy as np

from sensorispace_ros.core.naive.anchors import Snapshot, frontier_requests
from sensorispace_ros.core.naive.frontier import FrontierChoice
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.targets import (average_rows, averaged_targets, averages_targets,
    rows_to_average, target_repeats)


class _NoisyBody:
    """Senses ``truth[k]`` at motor state ``(k, 0)`` plus Gaussian noise
    ``sd``; counts the rows asked and whether each call was fresh."""

    def __init__(self, truth, sd, seed=0):
        self.truth, self.sd = np.asarray(truth, float), sd
        self.rng = np.random.default_rng(seed)
        self.rows, self.fresh_calls, self._fresh, self.stage = 0, 0, False, None

    @contextmanager
    def fresh(self):
        self._fresh = True
        try:
            yield
        finally:
            self._fresh = False

    def sense(self, states):
        states = np.asarray(states, float)
        self.rows += len(states)
        self.fresh_calls += int(self._fresh)
        clean = self.truth[states[:, 0].astype(int)]
        return clean + self.sd * self.rng.standard_normal(clean.shape)


def test_the_rows_of_fewest_sensings_are_averaged_in_turn():
    counts = np.array([5, 1, 1, 1, 1, 3])
    assert sorted(rows_to_average(counts, 2, event=0)) == [1, 2]
    assert sorted(rows_to_average(counts, 2, event=1)) == [2, 3]
    assert sorted(rows_to_average(counts, 2, event=2)) == [1, 4]
    assert sorted(rows_to_average(counts, 9, event=0)) == [0, 1, 2, 3, 4, 5]
    assert len(rows_to_average(counts, 0, event=0)) == 0


def test_averaged_rows_pool_their_sensings_with_the_sweeps():
    truth = np.array([[0.2] * 6, [0.5] * 6, [0.8] * 6])
    body = _NoisyBody(truth, sd=1e-2)
    states = np.column_stack([np.arange(3), np.zeros(3)])
    sweep = truth + np.array([[0.03] * 6, [0.0] * 6, [0.0] * 6])
    sensations, counts = average_rows(body, states, sweep, np.array([1, 1, 4]),
                                      np.array([0, 2]), repeats=399)
    assert list(counts) == [400, 1, 403]
    assert body.rows == 2 * 399 and body.fresh_calls == 1
    # Row 0: the sweep's error weighs 1/400; 399 fresh sensings average the noise.
    assert np.all(np.abs(sensations[0] - truth[0]) < 0.03 / 400 + 4 * 1e-2 / np.sqrt(399))
    assert np.array_equal(sensations[1], sweep[1])


def test_a_lost_sensing_is_left_out_of_the_average():
    class Lossy(_NoisyBody):
        def sense(self, states):
            out = super().sense(states)
            out[::2] = np.nan
            return out

    truth = np.array([[0.4] * 3])
    sensations, counts = average_rows(Lossy(truth, 0.0), np.zeros((1, 2)), truth.copy(),
                                      np.array([1]), np.array([0]), repeats=10)
    assert list(counts) == [6] and np.allclose(sensations, truth)


def _agent(noisy=True, repeats=64, noise=1e-3, weakest=0.002, separation=1.0, povs=5,
           budget=8):
    truth = np.linspace(0.1, 0.9, povs)[:, None] * np.ones(6)
    body = _NoisyBody(truth, noise)
    samples = np.zeros((povs, 4, 2))
    samples[:, :, 0] = np.arange(povs)[:, None]
    return SimpleNamespace(
        _noisy=noisy, _repeats=repeats, _event=3, _body=body,
        params=NaiveParams(averaged_targets=2, frontier_attempts=8, target_singular=4.0,
                           frontier_holes=False),
        _store=SimpleNamespace(samples=samples), _frontier_budget=lambda: budget,
        structure=SimpleNamespace(noise=noise, weakest=weakest),
        _max_pose_error=lambda: 0.03 * separation), truth


def test_a_target_is_sensed_as_often_as_lets_its_compensation_pass():
    for noise, singular, limit, end in ((1e-3, 0.008, 0.03, 64), (1e-3, 0.05, 0.006, 256),
                                        (1e-4, 0.02, 0.006, 16)):
        k = target_repeats(noise, singular, limit, end)
        error = lambda n: noise * np.sqrt(1.0 / n + 1.0 / end) / singular  # noqa: E731
        assert error(k) <= limit and (k == 1 or error(k - 1) > limit)
    # Where even an exact target would not pass, as often as the end.
    assert target_repeats(1e-3, 0.001, 0.03, 64) == 64


def test_a_snapshot_averages_rows_where_one_sensing_cannot_pin_a_pose():
    # One sensing: 1e-3 / 0.002 = 0.5 of pose error, against 0.03 allowed.
    agent, truth = _agent()
    sensations, counts = averaged_targets(agent, truth.copy(), np.ones(5, int))
    k = target_repeats(1e-3, 4.0 * 0.002, 0.03, 64)
    assert 1 < k < 64 and sorted(counts) == [1, 1, 1, k, k]
    assert agent._body.rows == 2 * (k - 1)
    # Rows already pooled from that many sensings are not sensed again.
    agent, truth = _agent()
    _, counts = averaged_targets(agent, truth.copy(), np.array([1, k, k, k, k]))
    assert list(counts) == [k] * 5 and agent._body.rows == k - 1


def test_fewer_rows_are_averaged_as_the_frontier_budget_falls():
    agent, truth = _agent(povs=40, budget=4)
    agent.params = NaiveParams(averaged_targets=16, frontier_attempts=8)
    _, counts = averaged_targets(agent, truth.copy(), np.ones(40, int))
    assert np.count_nonzero(counts > 1) == 8


def test_no_row_is_sensed_again_where_one_sensing_pins_the_pose():
    # weakest 0.02: one sensing fails at the start's weakest singular value
    # (0.05 > 0.03) but passes at four times it.
    for agent, _ in (_agent(weakest=0.1), _agent(weakest=0.02), _agent(noisy=False),
                     _agent(repeats=1), _agent(separation=np.inf)):
        assert not averages_targets(agent)
        sweep = np.full((5, 6), 0.5)
        sensations, counts = averaged_targets(agent, sweep, np.ones(5, int))
        assert agent._body.rows == 0
        assert np.array_equal(sensations, sweep) and list(counts) == [1] * 5


class _Chooser(FrontierChoice):
    """The frontier order of a stand-in agent's attributes."""

    def __init__(self, agent):
        self.__dict__.update(vars(agent))


def test_frontier_requests_take_the_rows_of_most_sensings_first():
    # Rows 0-1 matched; rows 2-4 unmatched, row 4 farthest in sensation
    # from the matched ones but averaged 257 times.
    rows = np.array([[0.1] * 6, [0.2] * 6, [0.3] * 6, [0.35] * 6, [0.9] * 6])
    samples = np.zeros((7, 4, 3))
    samples[:, :, 0] = np.arange(7)[:, None] * 0.2
    snap = Snapshot(0, rows, np.ones(5, int), np.zeros(6), np.zeros(3), -1,
                    counts=np.array([1, 1, 1, 1, 257]))
    matches = [(np.array([0, 1]), np.array([5, 6]))]
    averaging, _ = _agent()
    assert averages_targets(averaging)
    order = _Chooser(averaging)._frontier_order
    requests = frontier_requests([snap], matches, pov_samples=samples, attempts=8,
                                 budget=2, by_motor=True, order=order)
    assert [r.row for r in requests] == [4, 2] and requests[0].count == 257
    # Where the agent does not average targets the nearest rows come first.
    plain, _ = _agent(noisy=False)
    order = _Chooser(plain)._frontier_order
    for by_motor in (True, False):
        for kwargs in ({}, {"order": order}):
            requests = frontier_requests([snap], matches, pov_samples=samples, attempts=8,
                                         budget=2, by_motor=by_motor, **kwargs)
            assert [r.row for r in requests] == [2, 3]
