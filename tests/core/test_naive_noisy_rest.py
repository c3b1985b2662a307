"""What keeps a noisy naive agent's POVs on one lattice of positions: it
rests only on a compensation its matched neighbours hold (a far pose
sensing an unconfirmed anchor alike never becomes the pose every later
anchor is sensed from), averages the anchors that may be searched
unconfirmed as often as its budget allows, and takes a pose on a known
POV's loop for that POV (``test_known_loops``)."""
from types import SimpleNamespace

import numpy as np
import pytest

from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.anchors import Request, SnapshotMatching
from sensorispace_ros.core.naive.neighbours import Neighbours, loop_distances
from sensorispace_ros.core.naive.searching import SearchAndSample


def _records_agent(noisy, count=20, separation=0.1):
    """The parts of a NaiveAgent ``_compensation_records`` and ``_may_rest``
    read: two snapshots (the most recent first) and ``count`` known POVs
    ``separation`` apart."""
    agent = SimpleNamespace(
        _event=5, _noisy=noisy, _to_body=lambda m: np.array(m, float),
        _pool=[SimpleNamespace(event=4, rest_motor_state=np.zeros(4)),
               SimpleNamespace(event=3, rest_motor_state=np.ones(4))],
        _store=SimpleNamespace(count=count, samples=np.zeros((count, 2, 4)),
                               separation=lambda: separation),
        params=SimpleNamespace(pose_precision_povs=8))
    agent._may_rest = lambda k, requests: SnapshotMatching._may_rest(agent, k, requests)
    return agent


def _anchor(snapshot, reach):
    """A request for snapshot ``snapshot``'s anchor; ``reach``: its matched
    neighbours' distances (None: no match confirmed the snapshot)."""
    neighbours = None if reach is None else Neighbours(
        np.arange(len(reach)), np.arange(len(reach)), np.asarray(reach, float))
    return Request(snapshot, -1, np.zeros(6), np.zeros(4), neighbours=neighbours)


def test_a_noisy_agent_rests_only_on_a_compensation_its_neighbours_hold():
    # The most recent anchor (snapshot 0) was confirmed by no match: its
    # search may have ended on a far pose sensing it alike. The older one
    # (snapshot 1) has matched neighbours a separation away.
    unconfirmed, held = np.full(4, 0.25), np.full(4, 0.5)
    found_rest = {0: (2, unconfirmed), 1: (1, held)}
    requests = [_anchor(0, None), _anchor(1, [0.1, 0.2])]
    for noisy, rest, pov in ((True, held, 1), (False, unconfirmed, 2)):
        agent = _records_agent(noisy)
        records, choice = NaiveAgent._compensation_records(agent, {}, found_rest, requests, {})
        assert [r.pov for r in records] == [2, 1]       # both are compensations still
        assert choice[1] == pov and np.array_equal(choice[0], rest)


def test_a_noisy_agent_stays_where_no_neighbour_lies_near_the_anchor():
    # Matched neighbours, but the nearest lies 10 separations from the
    # anchor's POV: nothing holds a far pose there. A known POV matching an
    # anchor (no search) is rested on.
    requests = [_anchor(0, [1.0, 1.2])]
    agent = _records_agent(True)
    records, choice = NaiveAgent._compensation_records(
        agent, {}, {0: (2, np.full(4, 0.25))}, requests, {})
    assert len(records) == 1 and choice is None
    agent._store.samples[3, 0] = 0.75
    _, choice = NaiveAgent._compensation_records(agent, {1: 3}, {0: (2, np.full(4, 0.25))},
                                                 requests, {})
    assert choice[1] == 3 and np.array_equal(choice[0], np.full(4, 0.75))


def test_anchors_that_may_be_searched_unconfirmed_are_averaged_to_the_budget():
    # While fewer than unconfirmed_max_povs POVs are known an anchor may be
    # searched with no match to confirm its snapshot: it is averaged
    # accept_max_repeats times under random noise; later, and where
    # averaging does not pay (rounding: one sensing) or there is no noise,
    # as before.
    def repeats(count, noisy=True, given=16):
        agent = SimpleNamespace(_repeats=given, _noisy=noisy, _store=SimpleNamespace(count=count),
                                params=SimpleNamespace(unconfirmed_max_povs=100,
                                                       accept_max_repeats=256))
        return SearchAndSample._anchor_repeats(agent)

    assert repeats(1) == 256 and repeats(99) == 256
    assert repeats(100) == 16
    assert repeats(1, given=1) == 1 and repeats(1, noisy=False, given=1) == 1


def test_an_unconfirmed_anchors_compensation_is_refined_as_often_as_its_target():
    # Group 0: an anchor no match confirmed (no neighbours), its target of
    # 256 sensings; group 1: a frontier row held to its neighbours, of one.
    calls = []
    agent = SimpleNamespace(_repeats=16)
    agent._confirm = lambda solution, targets, counts, repeats=None: (
        calls.append((sorted(solution), repeats)) or dict(solution))
    requests = [_anchor(0, None), Request(1, 3, np.zeros(6), np.zeros(4),
                                          neighbours=Neighbours(np.zeros(1, int),
                                                                np.zeros(1, int),
                                                                np.full(1, 0.1)))]
    solution = {0: np.zeros(4), 1: np.ones(4)}
    kept = SearchAndSample._confirm_searched(agent, solution, np.zeros((2, 6)), {0: 256, 1: 1},
                                             requests, np.array([0, 1]))
    assert sorted(kept) == [0, 1]
    assert calls == [([1], None), ([0], 256)]


def _circle(center, radius=1.0, n=8):
    angle = np.linspace(0, 2 * np.pi, n, endpoint=False)
    loop = np.zeros((n, 4))
    loop[:, 0], loop[:, 1] = radius * np.cos(angle), radius * np.sin(angle)
    return loop + center


def test_a_pose_between_two_samples_lies_on_the_loop():
    loops = np.stack([_circle(0.0), _circle(np.array([3.0, 0, 0, 0]))])
    between = np.array([np.cos(np.pi / 8), np.sin(np.pi / 8), 0, 0])     # on the circle
    distance = loop_distances(between, loops)
    chord_gap = 1 - np.cos(np.pi / 8)                 # the chord's distance to the arc
    assert distance[0] == pytest.approx(chord_gap, rel=1e-9)
    assert np.min(np.linalg.norm(loops[0] - between, axis=1)) > 5 * distance[0]
    to_circle = np.linalg.norm(between[:2] - [3.0, 0.0]) - 1.0        # the far loop's circle
    assert to_circle <= distance[1] <= to_circle + chord_gap
    # On the torus of phases: a loop near +pi is near a point near -pi.
    wrapped = loop_distances(np.array([-np.pi + 0.01, 0, 0, 0]),
                             _circle(np.array([np.pi - 0.5, 0, 0, 0]), radius=0.3)[None])
    assert wrapped[0] < 0.25
