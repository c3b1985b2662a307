"""Frontier rows ordered by the lattice the equality sets imply
(core/naive/frontier_holes.py, ``HoleMap.row_targets``)."""
from types import SimpleNamespace

import numpy as np

from sensorispace_ros.core.naive.frontier_holes import REMEASURE_EVENTS, FrontierHoles
from sensorispace_ros.core.naive.hole_map import HoleMap
from sensorispace_ros.core.naive.lattice import Lattice
from sensorispace_ros.core.naive.params import NaiveParams

from test_lattice import _sets, _square_patch, _unimodular_map
from test_lattice_sets import _with_wrong_pairs

STEP = np.array([1, 0])


def _block_with_a_hole(unplaced: int = 0):
    """POVs on a 5 x 5 block of the lattice, its centre (2, 2) empty, and
    ``unplaced`` more POVs the map does not place."""
    points = [(i, j) for i in range(5) for j in range(5) if (i, j) != (2, 2)]
    ij = np.vstack([np.array(points), np.zeros((unplaced, 2), dtype=int)])
    placed = np.arange(len(ij)) < len(points)
    return HoleMap(Lattice(ij=ij, placed=placed, residual=0.0), n_sets=0), points


class _Agent(FrontierHoles):
    """The parts of a NaiveAgent ``FrontierHoles`` reads, its map given."""

    def __init__(self, holes, n_povs, noisy=True, frontier_holes=True, sets=None):
        self._noisy = noisy
        self.params = NaiveParams(frontier_holes=frontier_holes)
        self._store = SimpleNamespace(count=n_povs)
        self._sets = sets if sets is not None else SimpleNamespace(pairs=np.zeros((0, 2)))
        self._event = 0
        self._frontier_map = holes


def _rows_and_index(points, unplaced_row=None):
    """Rows whose targets (moved by ``STEP``) lie at the hole (2, 2), past
    the edge (5, 0), on a known POV (3, 3), and the POV ``unplaced_row``."""
    index = {p: i for i, p in enumerate(points)}
    rows = [index[(2, 3)], index[(4, 0)], index[(1, 2)]]
    if unplaced_row is not None:
        rows.insert(0, unplaced_row)
    return np.array(rows), index


def _matched(index):
    """A snapshot's matches that show the step ``STEP``."""
    return np.array([index[(0, 0)], index[(0, 1)]]), np.array([index[(1, 0)], index[(1, 1)]])


def test_row_targets_tell_known_points_empty_ones_and_their_known_neighbours():
    holes, points = _block_with_a_hole(unplaced=1)
    rows, _ = _rows_and_index(points, unplaced_row=len(points))
    targets, known, neighbours = holes.row_targets(rows, STEP)
    np.testing.assert_array_equal(targets[1:], [(3, 3), (5, 0), (2, 2)])
    assert known.tolist() == [False, True, False, False]
    assert neighbours.tolist() == [-1, 7, 2, 8]


def test_the_hole_comes_first_then_the_edge_then_unplaced_rows_and_known_targets_go():
    holes, points = _block_with_a_hole(unplaced=1)
    rows, index = _rows_and_index(points, unplaced_row=len(points))
    agent = _Agent(holes, len(points) + 1)
    order = agent._hole_order(np.arange(len(rows)), rows, _matched(index))
    assert rows[order].tolist() == [index[(1, 2)], index[(4, 0)], len(points)]
    assert agent._frontier_points == {index[(1, 2)]: (2, 2), index[(4, 0)]: (5, 0)}


def test_without_noise_a_map_or_the_parameter_the_order_is_kept():
    holes, points = _block_with_a_hole()
    rows, index = _rows_and_index(points)
    order = np.arange(len(rows))
    for agent in (_Agent(holes, len(points), noisy=False),
                  _Agent(holes, len(points), frontier_holes=False),
                  _Agent(None, len(points))):
        assert agent._hole_order(order, rows, _matched(index)).tolist() == [0, 1, 2]
    # Matches the map does not agree on show no step: the order is kept too.
    before, after = _matched(index)
    assert _Agent(holes, len(points))._hole_order(
        order, rows, (before, after[::-1])).tolist() == [0, 1, 2]


def test_a_new_pov_found_toward_the_hole_is_placed_there_and_its_point_is_known():
    holes, points = _block_with_a_hole()
    rows, index = _rows_and_index(points)
    agent = _Agent(holes, len(points) + 1)
    agent._hole_order(np.arange(len(rows)), rows, _matched(index))
    requests = [SimpleNamespace(row=-1), SimpleNamespace(row=index[(1, 2)]),
                SimpleNamespace(row=index[(4, 0)])]
    new = len(points)
    # The anchor (request 0) and the edge's search found nothing new.
    agent._place_frontier_finds(requests, {0: (3, None), 1: (new, None)}, [new])
    assert holes.placed[new] and tuple(holes.ij[new]) == (2, 2)
    assert not agent._frontier_points
    order = agent._hole_order(np.arange(len(rows)), rows, _matched(index))
    assert rows[order].tolist() == [index[(4, 0)]]


def _patch_sets(seed, wrong_share=0.0):
    points = _square_patch(seed, size=8)
    pairs, ids = _sets(points, 200, seed, max_pairs=12)
    if wrong_share:
        pairs, ids, _ = _with_wrong_pairs(points, pairs, ids, wrong_share, seed)
    return points, SimpleNamespace(pairs=pairs, set_ids=ids, n_sets=int(ids.max()) + 1)


def test_the_map_is_measured_from_the_sets_trimmed_where_a_wrong_pair_leaves_no_lattice():
    for share in (0.0, 0.02):
        points, sets = _patch_sets(1, share)
        agent = _Agent(None, len(points), sets=sets)
        holes = agent._frontier_holes()
        assert holes is not None and holes.placed.all()
        _unimodular_map(holes.ij, points)


def test_the_map_is_measured_again_once_unplaced_povs_pile_up_and_not_too_often():
    points, sets = _patch_sets(2)
    agent = _Agent(None, len(points), sets=sets)
    first = agent._frontier_holes()
    agent._store.count = len(points) + 3          # three POVs the map does not place
    agent._event = REMEASURE_EVENTS - 1
    assert agent._frontier_holes() is first and len(first.placed) == len(points) + 3
    agent._event = REMEASURE_EVENTS
    again = agent._frontier_holes()
    assert again is not first and len(again.placed) == len(points) + 3
    # Placed by the searches that found them, fewer than that: the map stands.
    again.place(len(points), (100, 100))
    again.place(len(points) + 1, (100, 101))
    agent._event = 10 * REMEASURE_EVENTS
    assert agent._frontier_holes() is again
