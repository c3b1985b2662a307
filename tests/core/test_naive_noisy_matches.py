"""How the naive agent matches its snapshots with a sweep under measured
noise: a statistical test against the noise of both sides, not the chain
tolerance (which, at noise 1e-3 on the paper grid, spans poses units apart)."""
from types import SimpleNamespace

import numpy as np

from sensorispace_ros.core.naive.anchors import Snapshot, SnapshotMatching
from sensorispace_ros.core.naive.params import NaiveParams

SD = 1e-3     # the noise the fake agent measured


def _agent(rows, rest, noisy=True, counts=None, rest_count=16):
    """The parts of a NaiveAgent ``_match_snapshots`` reads: one snapshot of
    ``rows`` (pooled ``counts`` each) and anchor ``rest`` (``rest_count``
    sensings), tolerances as the chain allowance sizes them (0.13)."""
    rows = np.asarray(rows, dtype=float)
    snap = Snapshot(0, rows, np.ones(len(rows), int), np.asarray(rest, dtype=float),
                    np.zeros(3), -1, counts=counts, rest_count=rest_count)
    tol = SimpleNamespace(match=0.13, separation=8.3 * SD, ratio=3.0)
    structure = SimpleNamespace(noise=SD, repeat_noise=SD, quantum=0.0)   # random noise
    return SimpleNamespace(_noisy=noisy, structure=structure, _tol=tol, _repeats=16,
                           params=NaiveParams(), _pool=[snap])


def _match(agent, current):
    matches, hits, _ = SnapshotMatching._match_snapshots(agent, np.asarray(current), None)
    before, after = matches[0]
    return dict(zip(before.tolist(), after.tolist())), hits.tolist()


ROWS = [[0.2] * 6, [0.5] * 6, [0.8] * 6]
REST = [0.35] * 6


def test_under_noise_a_row_matches_only_what_its_noise_explains():
    # Row 0 is sensed again within the noise; row 1's nearest sensation now
    # lies 12 sd per output away (within the chain tolerance, the third row
    # far beyond it); the anchor's nearest lies 10 sd away.
    current = [[0.2 + SD] * 6, [0.5 + 12 * SD] * 6, [0.9] * 6, [0.35 + 10 * SD] * 6]
    pairs, hits = _match(_agent(ROWS, REST, counts=np.ones(3)), current)
    assert pairs == {0: 0} and hits == [-1]


def test_under_noise_the_anchor_matches_a_pov_sensing_it_within_the_noise():
    current = [[0.9] * 6, [0.35 + SD] * 6]
    _, hits = _match(_agent(ROWS, REST, counts=np.ones(3)), current)
    assert hits == [1]


def test_under_noise_two_povs_within_the_noise_of_one_row_match_neither():
    current = [[0.5 + SD] * 6, [0.5 - SD] * 6, [0.9] * 6]
    pairs, _ = _match(_agent(ROWS, REST, counts=np.ones(3)), current)
    assert 1 not in pairs


def test_a_noiseless_agent_matches_by_its_tolerances():
    current = [[0.2 + SD] * 6, [0.5 + 12 * SD] * 6, [0.9] * 6, [0.35 + 10 * SD] * 6]
    pairs, hits = _match(_agent(ROWS, REST, noisy=False), current)
    assert pairs == {0: 0, 1: 1} and hits == [3]
