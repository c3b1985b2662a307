"""A noisy agent's compensation of an anchor no sweep row confirmed is
provisional: its POV is kept, its record waits until later matches show the
anchor's POV and the found POV at one relative pose, and is dropped when
their snapshots leave the pool. A noiseless agent records it at once."""
from types import SimpleNamespace

import numpy as np

from sensorispace_ros.core.naive.anchors import SnapshotMatching
from sensorispace_ros.core.naive.confirm import Provisional, settle_provisional
from sensorispace_ros.core.naive.records import CompensationRecord


def _record(event, anchor_event, pov):
    return CompensationRecord(event=event, anchor_event=anchor_event,
                              anchor_motor_state=np.zeros(4), motor_state=np.ones(4),
                              pov=pov, searched=True)


def _match(before, after):
    return np.asarray(before, dtype=int), np.asarray(after, dtype=int)


# The anchor of event 3 (the arm rested on POV 2) was compensated at event 7
# by POV 9; both events' snapshots are in the pool (event 7's first).
POOL = [SimpleNamespace(event=7), SimpleNamespace(event=3)]
PENDING = [Provisional(_record(7, 3, 9), rest_pov=2)]


def test_one_pov_matching_both_rows_confirms_a_provisional_compensation():
    # POV 5 now senses what POV 2 sensed at event 3 and what POV 9 sensed at 7.
    matches = [_match([9, 1], [5, 4]), _match([2], [5])]
    confirmed, pending = settle_provisional(PENDING, POOL, matches, {})
    assert confirmed == [PENDING[0].record] and pending == []


def test_a_hit_of_a_matched_snapshot_anchor_confirms_too():
    # No sweep row 2 matched, but the anchor (sensed at POV 2) was hit by POV 5
    # and another row of its snapshot matched.
    matches = [_match([9], [5]), _match([0], [8])]
    confirmed, _ = settle_provisional(PENDING, POOL, matches, {1: 5})
    assert confirmed == [PENDING[0].record]


def test_matches_that_disagree_leave_it_pending_and_a_lost_snapshot_drops_it():
    # A far alias: what POV 9 sensed is now sensed by another POV than POV 2's.
    matches = [_match([9], [6]), _match([2], [5])]
    confirmed, pending = settle_provisional(PENDING, POOL, matches, {})
    assert confirmed == [] and pending == PENDING
    # An unmatched anchor's hit alone confirms nothing either.
    confirmed, pending = settle_provisional(PENDING, POOL, [_match([9], [5]), _match([], [])],
                                            {1: 5})
    assert confirmed == [] and pending == PENDING
    # The anchor's snapshot left the pool: it can never be confirmed.
    confirmed, pending = settle_provisional(PENDING, POOL[:1], matches[:1], {})
    assert confirmed == [] and pending == []


def _agent(noisy):
    return SimpleNamespace(_noisy=noisy, _provisional=[],
                           _pool=[SimpleNamespace(event=4, rest_pov=1),
                                  SimpleNamespace(event=3, rest_pov=2)])


def test_a_noisy_agent_holds_back_the_record_of_an_unconfirmed_anchor():
    # Snapshot 0 (event 4) had a sweep match, snapshot 1 (event 3) none: the
    # records are snapshot 0's anchor, snapshot 1's anchor, then two frontier
    # rows, the second with no POV walked whole.
    matches = [_match([0], [3]), _match([], [])]
    anchor0, anchor1 = _record(5, 4, 7), _record(5, 3, 8)
    frontier, lone = _record(5, 4, 9), _record(5, 4, -1)
    records = [anchor0, anchor1, frontier, lone]
    found_rest = {0: (7, np.ones(4)), 1: (8, np.ones(4))}
    for noisy, kept in ((True, [anchor0, frontier]), (False, records)):
        out = SnapshotMatching._hold_unconfirmed(_agent(noisy), records, matches, {},
                                                 found_rest)
        assert out == kept
    held = _agent(True)
    SnapshotMatching._hold_unconfirmed(held, records, matches, {}, found_rest)
    assert [p.record for p in held._provisional] == [anchor1]
    assert held._provisional[0].rest_pov == 2
