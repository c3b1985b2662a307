"""Which frontier targets the naive agent searches under measured noise: a
target must stand out from the sensations like it."""
from types import SimpleNamespace

import numpy as np

from sensorispace_ros.core.naive.anchors import Request, Snapshot, SnapshotMatching
from sensorispace_ros.core.naive.params import NaiveParams

SD = 1e-3     # the noise the fake agent measured


def _agent(rows, noisy=True, counts=None):
    """The parts of a NaiveAgent ``_distinct_targets`` reads: one snapshot
    of ``rows`` (pooled ``counts`` each, None: one)."""
    rows = np.asarray(rows, dtype=float)
    snap = Snapshot(0, rows, np.ones(len(rows), int), np.zeros(rows.shape[1]),
                    np.zeros(3), -1, counts=counts)
    return SimpleNamespace(_noisy=noisy, structure=SimpleNamespace(noise=SD),
                           params=NaiveParams(), _body=SimpleNamespace(n_sensors=rows.shape[1]),
                           _pool=[snap])


def _frontier(agent, row):
    snap = agent._pool[0]
    return Request(0, row, snap.sensations[row], np.zeros(3), count=snap.count(row))


def _kept_rows(agent, requests, current):
    kept = SnapshotMatching._distinct_targets(agent, requests, current)
    return [r.row for r in kept]


def test_a_frontier_target_within_noise_of_another_row_is_not_searched():
    # Rows 0 and 1 differ by ~2 sd per output: two sensings of one pose
    # differ that much. Row 2 stands far from every sensation.
    rows = [[0.5] * 6, [0.5 + 2 * SD] * 6, [0.9] * 6, [0.1] * 6]
    agent = _agent(rows)
    requests = [_frontier(agent, i) for i in (0, 1, 2)]
    assert _kept_rows(agent, requests, np.zeros((0, 6))) == [2]
    # The same rows pooled from 400 sensings each stand out from each other.
    pooled = _agent(rows, counts=np.full(4, 400))
    requests = [_frontier(pooled, i) for i in (0, 1, 2)]
    assert _kept_rows(pooled, requests, np.zeros((0, 6))) == [0, 1, 2]


def test_a_target_a_known_pov_senses_now_within_noise_is_not_searched():
    # No match singled the known POV out (else the row would not be a
    # frontier row); a search would end on it or on the row's own pose.
    rows = [[0.2] * 6, [0.6] * 6, [0.9] * 6]
    agent = _agent(rows)
    current = np.array([[0.6 + SD] * 6, [0.9 + 10 * SD] * 6])
    requests = [_frontier(agent, i) for i in (0, 1, 2)]
    assert _kept_rows(agent, requests, current) == [0, 2]


def test_anchors_at_rest_are_searched_whatever_senses_like_them():
    rows = [[0.5] * 6, [0.5 + SD] * 6, [0.7] * 6]
    agent = _agent(rows)
    rest = Request(0, -1, np.full(6, 0.5), np.zeros(3), count=16)
    requests = [rest] + [_frontier(agent, i) for i in range(3)]
    assert _kept_rows(agent, requests, np.array([[0.5] * 6])) == [-1, 2]


def test_a_noiseless_agent_searches_every_target():
    rows = [[0.5] * 6, [0.5 + SD] * 6]
    agent = _agent(rows, noisy=False)
    requests = [_frontier(agent, i) for i in (0, 1)]
    assert _kept_rows(agent, requests, np.array([[0.5] * 6])) == [0, 1]
