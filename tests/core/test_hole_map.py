"""Which empty lattice points the agent searches (core/naive/hole_map.py)."""
import numpy as np

from sensorispace_ros.core.naive.hole_map import HoleMap
from sensorispace_ros.core.naive.lattice import Lattice


def _block_with_a_hole():
    """POVs on a 5 x 5 block of the lattice, its centre (2, 2) empty."""
    points = [(i, j) for i in range(5) for j in range(5) if (i, j) != (2, 2)]
    ij = np.array(points)
    return HoleMap(Lattice(ij=ij, placed=np.ones(len(ij), bool), residual=0.0), n_sets=0), points


def test_the_hole_comes_before_the_edge_and_known_targets_are_not_searched():
    holes, points = _block_with_a_hole()
    index = {p: i for i, p in enumerate(points)}
    step = np.array([1, 0])
    # Rows whose targets lie at (2, 2) (the hole, 8 known neighbours), at
    # (5, 0) (past the edge, 2 known neighbours), at (3, 3) (a known POV).
    rows = [index[(1, 2)], index[(4, 0)], index[(2, 3)]]
    found = holes.candidates([(0, rows, step)], max_fails=2)
    assert [c.point for c in found] == [(2, 2), (5, 0)]
    assert found[0].row == index[(1, 2)] and found[0].snapshot == 0
    # The search starts from a known POV next to the point, along an axis.
    neighbour = np.array(points[found[0].neighbour])
    assert np.abs(neighbour - (2, 2)).sum() == 1


def test_a_point_is_searched_once_per_reaction_and_given_up_after_its_failures():
    holes, points = _block_with_a_hole()
    index = {p: i for i, p in enumerate(points)}
    # Two snapshots point at the hole: one search, the most recent snapshot's.
    targets = [(0, [index[(1, 2)]], np.array([1, 0])), (1, [index[(2, 1)]], np.array([0, 1]))]
    found = holes.candidates(targets, max_fails=2)
    assert [(c.point, c.snapshot) for c in found] == [((2, 2), 0)]
    holes.failed((2, 2))
    assert [c.point for c in holes.candidates(targets, max_fails=2)] == [(2, 2)]
    holes.failed((2, 2))
    assert holes.candidates(targets, max_fails=2) == []
    assert [c.point for c in holes.candidates(targets, max_fails=3)] == [(2, 2)]


def test_a_failed_point_waits_behind_one_never_tried_with_as_many_neighbours():
    holes, points = _block_with_a_hole()
    index = {p: i for i, p in enumerate(points)}
    # (5, 1) and (5, 3) past the right edge, 3 known neighbours each.
    targets = [(0, [index[(4, 1)], index[(4, 3)]], np.array([1, 0]))]
    holes.failed((5, 1))
    assert [c.point for c in holes.candidates(targets, max_fails=4)] == [(5, 3), (5, 1)]


def test_the_displacement_is_read_only_where_every_placed_pair_agrees():
    holes, points = _block_with_a_hole()
    index = {p: i for i, p in enumerate(points)}
    before = np.array([index[(0, 0)], index[(1, 1)]])
    np.testing.assert_array_equal(
        holes.displacement(before, np.array([index[(1, 0)], index[(2, 1)]])), [1, 0])
    assert holes.displacement(before, np.array([index[(1, 0)], index[(1, 2)]])) is None
    holes.grow(len(points) + 1)             # a POV the map does not place
    assert holes.unplaced == 1
    assert holes.displacement(np.array([len(points)]), np.array([0])) is None


def test_a_found_pov_is_placed_at_its_point_and_is_no_target_any_more():
    holes, points = _block_with_a_hole()
    index = {p: i for i, p in enumerate(points)}
    targets = [(0, [index[(1, 2)]], np.array([1, 0]))]
    holes.place(len(points), (2, 2))
    assert holes.unplaced == 0 and holes.found == 1
    assert holes.candidates(targets, max_fails=2) == []


def test_failures_follow_the_points_when_the_lattice_is_measured_again():
    # Measured again, the lattice may come in another basis and origin (an
    # integer map of determinant +-1): a point's failures stay with the point.
    holes, points = _block_with_a_hole()
    holes.failed((5, 0))
    holes.failed((5, 0))
    unimodular = np.array([[0, 1], [1, 1]])
    moved = np.array(points) @ unimodular + (3, -2)
    again = holes.remeasured(Lattice(ij=moved, placed=np.ones(len(points), bool),
                                     residual=0.0), n_sets=10)
    point = tuple((np.array([5, 0]) @ unimodular + (3, -2)).tolist())
    assert again.fails == {point: 2} and again.n_sets == 10 and again.found == 0
    index = {p: i for i, p in enumerate(points)}
    step = np.array([1, 0]) @ unimodular
    targets = [(0, [index[(4, 0)]], step)]
    assert again.candidates(targets, max_fails=2) == []


def test_a_set_that_moves_placed_povs_by_two_steps_contradicts_the_map():
    holes, points = _block_with_a_hole()
    index = {p: i for i, p in enumerate(points)}
    agree = [(index[(0, 0)], index[(1, 0)]), (index[(3, 3)], index[(4, 3)]),
             (index[(0, 1)], index[(0, 3)]), (index[(1, 1)], index[(1, 3)])]
    ids = [0, 0, 1, 1]
    assert not holes.contradicted(np.array(agree), np.array(ids))
    # The same pair in another set moved by another step: a wrong equality.
    wrong = agree + [(index[(2, 1)], index[(3, 1)])]
    assert holes.contradicted(np.array(wrong), np.array(ids + [1]))
    # A pair with a POV the map does not place says nothing about the map.
    unplaced = agree + [(index[(2, 1)], len(points))]
    assert not holes.contradicted(np.array(unplaced), np.array(ids + [1]))
