"""A frontier compensation under noise is held to its row's matched
neighbours: one displacement moved every pose, so the row's neighbours'
partners lie around its compensation (``neighbours.held_by_neighbours``)."""
from types import SimpleNamespace

import numpy as np

from sensorispace_ros.core.naive import anchors
from sensorispace_ros.core.naive.anchors import (RANK_FULL, Snapshot, SnapshotMatching,
    frontier_requests)
from sensorispace_ros.core.naive.neighbours import (curve_distances, held_by_neighbours,
    matched_neighbours)


def _curves(centres, n=20, length=0.05):
    """POVs as short straight curves (n samples) through ``centres`` (K, 2)."""
    t = np.linspace(-length, length, n)[:, None]
    centres = np.asarray(centres, dtype=float)
    return centres[:, None, :] + t * np.array([1.0, 0.0])


def _grid(shift):
    """Nine POVs on a 3 x 3 grid of step 0.3 (rows 0-8, row 4 the centre),
    then the same nine moved by ``shift`` (rows 9-17, the known POVs after
    the displacement) and one far from all (row 18)."""
    axis = 1.0 + 0.3 * np.arange(-1, 2)
    before = np.stack(np.meshgrid(axis, axis, indexing="ij"), axis=-1).reshape(-1, 2)
    far = before[4] + shift + np.array([0.0, -2.0])
    return _curves(np.vstack([before, before + shift, far[None]]))


SHIFT = np.array([0.0, 0.9])
RATIO, SLACK = anchors._NEIGHBOUR_RATIO, 0.15
# The centre row is the frontier row: its eight neighbours are matched.
BEFORE = np.array([0, 1, 2, 3, 5, 6, 7, 8])


def test_curve_distances_wrap_around_the_torus():
    curves = _curves([[np.pi - 0.01, 0.0]], n=1, length=0.0)
    assert np.allclose(curve_distances(np.array([-np.pi + 0.01, 0.0]), curves), 0.02)


def test_a_compensation_among_the_neighbours_partners_is_held_a_far_one_is_not():
    samples = _grid(SHIFT)
    neighbours = matched_neighbours(samples, BEFORE, BEFORE + 9, samples[4, 10])
    assert set(neighbours.before[:4]) == {1, 3, 5, 7}        # the four sides, then a corner
    assert list(neighbours.after) == list(neighbours.before + 9)
    right = samples[4, 10] + SHIFT
    assert held_by_neighbours(samples, neighbours, right, ratio=RATIO, slack=SLACK)
    far = samples[18, 3]            # a far pose sensing the target alike
    assert not held_by_neighbours(samples, neighbours, far, ratio=RATIO, slack=SLACK)


def test_one_wrong_match_among_the_neighbours_is_outvoted():
    samples = _grid(SHIFT)
    after = BEFORE + 9
    after[3] = 18               # row 5 wrongly matched to the far POV (it sensed alike)
    neighbours = matched_neighbours(samples, BEFORE, after, samples[4, 10])
    assert 18 in neighbours.after
    right = samples[4, 10] + SHIFT
    assert held_by_neighbours(samples, neighbours, right, ratio=RATIO, slack=SLACK)
    # A compensation beside the wrong partner agrees with it alone.
    beside_wrong = samples[18, 10] + np.array([0.0, 0.05])
    assert not held_by_neighbours(samples, neighbours, beside_wrong, ratio=RATIO, slack=SLACK)


def _pool(samples, sensations):
    snap = Snapshot(0, np.asarray(sensations, dtype=float), np.full(len(sensations), RANK_FULL),
                    np.zeros(2), samples[0, 0], 0)
    return [snap]


def test_by_motor_the_start_is_the_partner_of_the_nearest_pov_in_motor_space():
    samples = _grid(SHIFT)
    # The centre row's sensation is most like row 0's; in motor space row 1
    # (the side its first sample lies toward) is the nearest matched row.
    sensations = np.linspace(0.1, 0.9, 9)[:, None]
    sensations[4] = sensations[0] + 1e-4
    pool = _pool(samples, sensations)
    matches = [(BEFORE, BEFORE + 9)]
    plain = frontier_requests(pool, matches, pov_samples=samples, attempts=8, budget=1)
    assert plain[0].row == 4 and np.allclose(plain[0].start, samples[9, 0])
    assert plain[0].neighbours is None
    moved = frontier_requests(pool, matches, pov_samples=samples, attempts=8, budget=1,
                              by_motor=True)
    assert moved[0].row == 4 and np.allclose(moved[0].start, samples[10, 0])
    assert moved[0].neighbours.after[0] == 10


def test_the_agent_drops_far_frontier_solutions_only_under_noise():
    samples = _grid(SHIFT)
    sensations = np.linspace(0.1, 0.9, 9)[:, None]
    pool = _pool(samples, sensations)
    matches = [(np.array([0, 1, 2, 3, 6, 7, 8]), np.array([9, 10, 11, 12, 15, 16, 17]))]
    requests = frontier_requests(pool, matches, pov_samples=samples, attempts=8, budget=2,
                                 by_motor=True)
    assert sorted(r.row for r in requests) == [4, 5]
    store = SimpleNamespace(samples=samples, separation=lambda: SLACK)
    solution = {0: samples[requests[0].row, 10] + SHIFT, 1: samples[18, 10]}
    group = np.array([0, 1])
    agent = SimpleNamespace(_noisy=True, _store=store)
    assert list(SnapshotMatching._held_by_neighbours(agent, solution, requests, group)) == [0]
    agent._noisy = False
    assert list(SnapshotMatching._held_by_neighbours(agent, solution, requests, group)) == [0, 1]


def test_a_compensation_on_a_neighbours_partner_is_not_the_rows():
    samples = _grid(SHIFT)
    neighbours = matched_neighbours(samples, BEFORE, BEFORE + 9, samples[4, 10])
    # Every neighbour's partner lies a lattice step from the right pose; the
    # pose of one of them is not the row's (it is that neighbour's).
    on_partner = samples[neighbours.after[0], 10]
    assert not held_by_neighbours(samples, neighbours, on_partner, ratio=RATIO, slack=SLACK)
