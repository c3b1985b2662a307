"""Which frontier rows the naive agent searches (``frontier.FrontierChoice``):
with ``frontier_give_way`` under noise, not a target a remembered split
POV senses now, and the rows whose searches failed least often first; with
``frontier_skip_split`` alone, not those targets, the rest nearest first;
otherwise the nearest in sensation first."""
from types import SimpleNamespace

import numpy as np
import pytest

from sensorispace_ros.core.naive.anchors import Snapshot, frontier_requests
from sensorispace_ros.core.naive.equality_sets import RANK_FULL
from sensorispace_ros.core.naive.frontier import FrontierChoice
from sensorispace_ros.core.naive.params import NaiveParams

SD = 1e-3     # the noise the fake agent measured


class _Agent(FrontierChoice):
    """The parts of a NaiveAgent ``FrontierChoice`` reads."""

    def __init__(self, n_povs, n_sensors, noisy=True, split_now=(), give_way=True,
                 skip_split=False):
        self._noisy = noisy
        self.structure = SimpleNamespace(noise=SD)
        self.params = NaiveParams(frontier_give_way=give_way, frontier_skip_split=skip_split,
                                  frontier_holes=False)
        self._body = SimpleNamespace(n_sensors=n_sensors)
        self._store = SimpleNamespace(count=n_povs)
        self._split_now = np.asarray(split_now, dtype=float).reshape(-1, n_sensors)
        self._frontier_success = 1.0


def _world():
    """A snapshot of 6 POVs of one sensor: rows 0 and 1 matched (POVs 6
    and 7 now), rows 2-5 not, row 2 sensing most like a matched row."""
    sensations = np.array([[0.10], [0.20], [0.22], [0.30], [0.50], [0.90]])
    snap = Snapshot(0, sensations, np.full(6, RANK_FULL), np.zeros(1), np.zeros(2), 0)
    samples = np.arange(8 * 4 * 2, dtype=float).reshape(8, 4, 2)
    return [snap], [(np.array([0, 1]), np.array([6, 7]))], samples


def _rows(agent, budget):
    pool, matches, samples = _world()
    requests = frontier_requests(pool, matches, pov_samples=samples, attempts=8, budget=budget,
                                 order=agent._frontier_order)
    return [r.row for r in requests]


def _searched(agent, rows, new=()):
    """``_track_frontier`` after searches of frontier ``rows`` (an anchor's
    at row -1 too) that found POVs ``new`` (request ``i`` found POV 100 + i)."""
    requests = [SimpleNamespace(row=-1)] + [SimpleNamespace(row=r) for r in rows]
    found = {i: (100 + i, None) for i in range(len(requests))}
    agent._track_frontier(requests, found, [100 + i for i in new])


def test_noiseless_the_nearest_rows_in_sensation_come_first_however_often_they_failed():
    agent = _Agent(8, 1, noisy=False, split_now=[[0.22]])
    assert _rows(agent, 2) == [2, 3]
    _searched(agent, [2, 3])
    assert _rows(agent, 2) == [2, 3]


def test_without_frontier_give_way_the_noisy_order_is_the_nearest_first_too():
    agent = _Agent(8, 1, split_now=[[0.22 + SD]], give_way=False)
    assert _rows(agent, 2) == [2, 3]
    _searched(agent, [2, 3])
    assert _rows(agent, 2) == [2, 3]


def test_a_target_a_remembered_split_pov_senses_now_gives_its_turn_to_the_next_row():
    # Row 2's target is sensed now, within the noise, by a split POV's
    # state: a search would end on that loop, walked and found split.
    agent = _Agent(8, 1, split_now=[[0.22 + SD], [5.0]])
    assert _rows(agent, 2) == [3, 4]
    # A split POV sensing something else leaves the rows as they were.
    assert _rows(_Agent(8, 1, split_now=[[0.22 + 50 * SD]]), 2) == [2, 3]


def test_rows_whose_searches_failed_least_often_come_first_under_noise():
    agent = _Agent(8, 1)
    assert _rows(agent, 2) == [2, 3]
    # Row 2's search found a new POV (request 1), row 3's found none; the
    # anchor's request (row -1) is no frontier row's.
    _searched(agent, [2, 3], new=[1])
    assert list(agent._frontier_fails()) == [0, 0, 0, 1, 0, 0, 0, 0]
    assert _rows(agent, 3) == [2, 4, 5]
    assert agent._frontier_success == pytest.approx(0.9 + 0.1 * 0.5)
    _searched(agent, [2, 4, 5])
    assert _rows(agent, 4) == [2, 3, 4, 5]
    _searched(agent, [2])
    assert _rows(agent, 4) == [3, 4, 5, 2]


def test_the_failures_grow_with_the_povs_found():
    agent = _Agent(3, 1)
    _searched(agent, [2])
    agent._store.count = 5
    assert list(agent._frontier_fails()) == [0, 0, 1, 0, 0]


def test_skipping_split_targets_alone_keeps_the_rest_nearest_first_however_often_they_failed():
    agent = _Agent(8, 1, split_now=[[0.22 + SD]], give_way=False, skip_split=True)
    assert _rows(agent, 2) == [3, 4]
    _searched(agent, [3, 4])
    assert _rows(agent, 3) == [3, 4, 5]                  # failures change no turn
    # Noiseless, or no split POV sensing the target: nothing is skipped.
    assert _rows(_Agent(8, 1, noisy=False, split_now=[[0.22]], give_way=False,
                        skip_split=True), 2) == [2, 3]
    assert _rows(_Agent(8, 1, split_now=[[0.22 + 50 * SD]], give_way=False,
                        skip_split=True), 2) == [2, 3]
