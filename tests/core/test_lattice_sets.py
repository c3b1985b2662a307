"""The lattice of equality sets that hold wrong pairs, and the sets it implies
(core/naive/lattice_sets.py)."""
import numpy as np
import pytest

from sensorispace_ros.core.naive.lattice import Lattice, lattice_coordinates
from sensorispace_ros.core.naive.lattice_sets import (implied_sets, lattice_equalities,
                                                      pair_support, set_medians, sliding_povs,
                                                      tied_twice, trimmed_lattice)

from test_lattice import _sets, _square_patch, _unimodular_map


def _with_wrong_pairs(points, pairs, ids, share: float, seed: int):
    """``pairs``/``ids`` with ``share`` of the pairs' ends moved to another
    POV one to three steps from the right one (a match with a neighbour);
    returns them and which pairs are wrong."""
    rng = np.random.default_rng(seed)
    index = {tuple(p): i for i, p in enumerate(points.tolist())}
    pairs = pairs.copy()
    wrong = np.zeros(len(pairs), dtype=bool)
    for k in rng.choice(len(pairs), size=int(share * len(pairs)), replace=False):
        for _ in range(20):
            off = rng.integers(-3, 4, size=points.shape[1])
            partner = index.get(tuple(points[pairs[k, 1]] + off))
            if off.any() and partner is not None and partner != pairs[k, 0]:
                pairs[k, 1], wrong[k] = partner, True
                break
    return pairs, ids, wrong


def test_set_medians_are_each_sets_median():
    rng = np.random.default_rng(0)
    ids = rng.integers(0, 40, size=500)
    values = rng.normal(size=(500, 2))
    medians = set_medians(values, ids)
    for s in np.unique(ids):
        np.testing.assert_allclose(medians[ids == s], np.median(values[ids == s], axis=0)[None]
                                   .repeat(np.count_nonzero(ids == s), axis=0))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_wrong_pairs_are_dropped_and_the_lattice_is_the_truth(seed):
    # Two percent of the pairs matched a neighbour of the right POV: the exact
    # test finds no lattice; trimmed, every wrong pair is dropped, few right
    # ones, and every POV sits where the truth puts it.
    points = _square_patch(seed)
    pairs, ids = _sets(points, 400, seed, max_pairs=12)
    pairs, ids, wrong = _with_wrong_pairs(points, pairs, ids, 0.02, seed)
    assert wrong.sum() >= 10
    assert lattice_coordinates(pairs, ids, len(points)) is None
    lattice, kept = trimmed_lattice(pairs, ids, len(points))
    assert lattice is not None and lattice.placed.all()
    assert not np.any(kept & wrong)
    assert np.count_nonzero(~kept & ~wrong) <= 0.05 * np.count_nonzero(~wrong)
    _unimodular_map(lattice.ij, points)


def test_sets_without_wrong_pairs_are_kept_whole():
    points = _square_patch(3)
    pairs, ids = _sets(points, 300, 3)
    lattice, kept = trimmed_lattice(pairs, ids, len(points))
    assert kept.all()
    np.testing.assert_array_equal(lattice.ij, lattice_coordinates(pairs, ids, len(points)).ij)


def test_three_dimensions_give_no_lattice_even_trimmed():
    cube = np.array([(i, j, k) for i in range(6) for j in range(6) for k in range(6)])
    pairs, ids = _sets(cube, 400, 7)
    assert trimmed_lattice(pairs, ids, len(cube))[0] is None
    found = lattice_equalities(pairs, ids, len(cube), 1)
    assert len(found.pairs) == 0 and found.placed == 0


def test_pair_support_counts_distinct_sets():
    pairs = np.array([[0, 1], [0, 2], [1, 2], [0, 3], [3, 4]])
    ids = np.array([0, 0, 1, 1, 1])
    # POV 0: sets 0 and 1; 1: 0 and 1; 2: 0 and 1; 3: set 1; 4: set 1; 5: none.
    np.testing.assert_array_equal(pair_support(pairs, ids, 6), [2, 2, 2, 1, 1, 0])


def test_implied_sets_hold_every_two_usable_povs_by_their_step():
    ij = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [5, 5]])
    lattice = Lattice(ij=ij, placed=np.array([1, 1, 1, 1, 1, 0], bool), residual=0.0)
    usable = np.array([1, 1, 1, 1, 0, 1], bool)         # POV 4 unusable, POV 5 not placed
    pairs, ids = implied_sets(lattice, usable)
    steps = ij[pairs[:, 1]] - ij[pairs[:, 0]]
    for s in np.unique(ids):
        assert len(np.unique(steps[ids == s], axis=0)) == 1
        assert np.count_nonzero(ids == s) >= 2
    assert np.array_equal(np.unique(ids), np.arange(ids.max() + 1))
    assert not np.isin(pairs, [4, 5]).any()
    # Steps (1, 0): 0->1, 1->2; (0, 1) has one pair only (0->3): no set.
    got = {tuple(p) for p in pairs.tolist()}
    assert {(0, 1), (1, 2)} <= got and (0, 3) not in got


def test_a_pov_tied_by_few_sets_is_left_out_of_the_implied_sets():
    points = _square_patch(8)
    pairs, ids = _sets(points, 300, 8)
    # One more POV, in one pair of one set: the lattice places it, but on
    # that one pair alone.
    stray = len(points)
    pairs = np.vstack([pairs, [[0, stray]]])
    ids = np.append(ids, ids[0])
    support = pair_support(pairs, ids, stray + 1)
    assert support[stray] == 1 and support[:stray].min() >= 2
    found = lattice_equalities(pairs, ids, stray + 1, support=2)
    assert found.placed == stray + 1 and found.usable == stray
    assert not np.isin(found.pairs, stray).any()
    assert np.isin(np.arange(stray), found.pairs).all()
    taken = lattice_equalities(pairs, ids, stray + 1, support=1)
    assert np.isin(stray, taken.pairs)


def _implying_agent(lattice_sets: bool, pairs, ids, n_povs):
    from types import SimpleNamespace

    from sensorispace_ros.core.naive.equality_sets import EqualitySetCollection
    from sensorispace_ros.core.naive.lattice_sets import ImpliedSets

    agent = ImpliedSets()
    agent.params = SimpleNamespace(lattice_sets=lattice_sets, lattice_support=1)
    agent._store = SimpleNamespace(count=n_povs, samples=None)
    agent._sets = EqualitySetCollection()
    for s in np.unique(ids):
        agent._sets.add(pairs[ids == s, 0], pairs[ids == s, 1])
    return agent


def test_the_agents_sets_are_the_found_then_the_implied_and_their_rows():
    points = _square_patch(2)
    pairs, ids = _sets(points, 200, 2)
    on = _implying_agent(True, pairs, ids, len(points))
    found_pairs, found_ids = on._found_sets()
    all_pairs, all_ids = on.equality_sets()
    n_found = len(found_pairs)
    assert len(all_pairs) > n_found
    np.testing.assert_array_equal(all_pairs[:n_found], found_pairs)
    rows = on.implied_rows()
    np.testing.assert_array_equal(rows[:, 1:], all_pairs[n_found:])
    np.testing.assert_array_equal(rows[:, 0], all_ids[n_found:])
    assert rows[:, 0].min() == found_ids.max() + 1
    off = _implying_agent(False, pairs, ids, len(points))
    np.testing.assert_array_equal(off.equality_sets()[0], found_pairs)
    assert len(off.implied_rows()) == 0


@pytest.mark.parametrize("seed", [0, 1])
def test_the_agent_withdraws_the_found_pairs_its_lattice_drops(seed):
    # Every wrong pair leaves the sets the representation gets, few right
    # ones do, the found pairs keep their order, and withdrawn_rows names
    # exactly the pairs that left (the graph's agent withdraws those rows).
    points = _square_patch(seed)
    pairs, ids = _sets(points, 400, seed, max_pairs=12)
    pairs, ids, wrong = _with_wrong_pairs(points, pairs, ids, 0.02, seed)
    agent = _implying_agent(True, pairs, ids, len(points))
    found_pairs, found_ids = agent._found_sets()
    gone = agent.withdrawn_rows()
    found_rows = np.column_stack([found_ids, found_pairs])
    left = ~(found_rows[:, None, :] == gone[None, :, :]).all(axis=2).any(axis=1)
    truly_wrong = {tuple(r) for r in np.column_stack([ids, pairs])[wrong].tolist()}
    assert truly_wrong <= {tuple(r) for r in gone.tolist()}
    assert len(gone) - len(truly_wrong) <= 0.05 * len(pairs)
    all_pairs, all_ids = agent.equality_sets()
    n_left = int(left.sum())
    np.testing.assert_array_equal(all_pairs[:n_left], found_pairs[left])
    np.testing.assert_array_equal(all_ids[:n_left], found_ids[left])
    assert len(all_pairs) > n_left
    assert not {tuple(r) for r in np.column_stack([all_ids, all_pairs]).tolist()} & truly_wrong


def test_pairs_left_out_only_for_sliding_are_not_withdrawn():
    # A chain that can slide keeps the lattice from the whole sets; the
    # lattice of the POVs tied twice holds, and the chain's pairs, which
    # disagree with nothing, stay with the representation.
    points = _square_patch(2)
    pairs, ids = _sets(points, 300, 2)
    pairs, ids, n = _with_sliding_chain(points, pairs, ids)
    found = lattice_equalities(pairs, ids, n, support=1)
    assert found.placed == len(points) and not found.kept[-3:].any()
    assert not found.withdrawn.any()
    agent = _implying_agent(True, pairs, ids, n)
    assert len(agent.withdrawn_rows()) == 0
    np.testing.assert_array_equal(agent.equality_sets()[0][:len(pairs)], agent._found_sets()[0])


def test_places_vouched_for_in_another_basis_join_the_lattice():
    from sensorispace_ros.core.naive.lattice_sets import with_vouched

    truth = np.array([(i, j) for i in range(5) for j in range(5)])
    placed = np.ones(len(truth), bool)
    placed[24] = False                            # the lattice does not place POV 24
    lattice = Lattice(ij=np.where(placed[:, None], truth, 0), placed=placed, residual=0.0)
    usable = placed.copy()
    usable[[3, 7]] = False                        # tied by too few sets
    # The other placement: another basis of the same lattice, shifted; it
    # places POV 3 where the lattice does, POV 7 elsewhere, POV 24 alone.
    other = truth @ np.array([[1, 1], [0, 1]]) + (2, -1)
    other[7] += (1, 0)
    grown, taken = with_vouched(lattice, usable, other, np.ones(len(truth), bool))
    assert grown.placed.all()
    np.testing.assert_array_equal(grown.ij[24], truth[24])
    assert taken[3] and taken[24] and not taken[7]
    np.testing.assert_array_equal(grown.ij[:24], lattice.ij[:24])
    # A placement that disagrees on a usable POV is not taken at all.
    other[0] += (0, 1)
    same, untouched = with_vouched(lattice, usable, other, np.ones(len(truth), bool))
    assert same is lattice and not untouched[3]


def _with_sliding_chain(points, pairs, ids):
    """Three more POVs, off the patch, that only a set of two pairs with no
    other member (its step free) and one more pair tie to it: they can slide
    together without breaking any set."""
    n = len(points)
    free, other = ids.max() + 1, ids[0]
    chain = np.array([[0, n], [n + 1, n + 2], [n, n + 1]])
    return (np.vstack([pairs, chain]), np.r_[ids, free, free, other], n + 3)


def test_povs_fewer_than_two_sets_tie_are_left_out_until_none_is():
    points = _square_patch(2)
    pairs, ids = _sets(points, 300, 2)
    pairs, ids, n = _with_sliding_chain(points, pairs, ids)
    kept = tied_twice(pairs, ids, n)
    # The chain's POV n + 2 is in the free set alone, then n + 1 is in one
    # set, then n: every chain pair goes, every other POV stays tied twice.
    assert not kept[-3:].any()
    assert np.all(pair_support(pairs[kept], ids[kept], n)[:len(points)] >= 2)
    assert kept[:-3].sum() >= 0.95 * (len(kept) - 3)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_trimmed_lattice_spans_the_plane_with_a_sliding_chain_and_wrong_pairs(seed):
    # A chain that can slide adds a null direction, and wrong pairs lift the
    # plane's own: the trimmed lattice is still the plane's (not a line
    # through it), and the chain is not placed.
    points = _square_patch(seed)
    pairs, ids = _sets(points, 400, seed, max_pairs=12)
    pairs, ids, wrong = _with_wrong_pairs(points, pairs, ids, 0.02, seed)
    pairs, ids, n = _with_sliding_chain(points, pairs, ids)
    lattice, kept = trimmed_lattice(pairs, ids, n)
    assert lattice is not None and lattice.dim == 2
    assert not lattice.placed[len(points):].any()
    assert not np.any(kept[:len(wrong)] & wrong)
    _unimodular_map(lattice.ij[:len(points)][lattice.placed[:len(points)]],
                    points[lattice.placed[:len(points)]])


def test_no_pairs_and_lone_sets_leave_nothing_tied():
    assert tied_twice(np.zeros((0, 2), dtype=int), np.zeros(0, dtype=int), 3).shape == (0,)
    # One set of two pairs ties each POV once: nothing is tied twice.
    assert not tied_twice(np.array([[0, 1], [2, 3]]), np.array([0, 0]), 4).any()


def test_a_plane_is_one_to_one_but_for_a_few_povs_walked_twice():
    from sensorispace_ros.core.naive.lattice_sets import MAX_SHARED, _a_plane

    points = _square_patch(5)
    placed = np.ones(len(points), dtype=bool)
    assert _a_plane(Lattice(ij=points, placed=placed, residual=0.0))
    twice = int(MAX_SHARED * len(points))
    walked_twice = np.vstack([points, points[:twice]])
    assert _a_plane(Lattice(ij=walked_twice, placed=np.ones(len(walked_twice), bool),
                            residual=0.0))
    # A plane folded onto a strip two points wide: whole rows on one point.
    strip = np.stack([points[:, 0] + 7 * (points[:, 1] // 2), points[:, 1] % 2], axis=1)
    assert not _a_plane(Lattice(ij=strip, placed=placed, residual=0.0))
    assert not _a_plane(Lattice(ij=points[:, :1], placed=placed, residual=0.0))
    assert not _a_plane(None)


def _with_sliding_pair(points, pairs, ids, steps=((1, 0), (0, 2), (-2, 1))):
    """Two more POVs, one step apart, tied to the patch only by sets that
    hold one pair of each (a snapshot in which only their two rows matched),
    one set per step of ``steps``: every set holds them twice, yet the two
    can slide together, each set's step free to follow."""
    n, index = len(points), {tuple(p): i for i, p in enumerate(points.tolist())}
    first = np.array([5, 5])
    extra, extra_ids = [], []
    for k, step in enumerate(steps):
        one, two = index.get(tuple(first + step)), index.get(tuple(first + (1, 0) + step))
        assert one is not None and two is not None
        extra += [[n, one], [n + 1, two]]
        extra_ids += [ids.max() + 1 + k] * 2
    return np.vstack([pairs, extra]), np.r_[ids, extra_ids], n + 2


def test_two_povs_that_slide_together_are_left_out_and_the_plane_is_found():
    # The sliding pair adds a null direction of its own: no plane's lattice
    # holds with its pairs, trimmed or tied twice; without them it does, with
    # every POV of the patch placed, and the pair's pairs are not withdrawn
    # (nothing says they are wrong).
    points = np.array([(i, j) for i in range(12) for j in range(12)])
    pairs, ids = _sets(points, 300, 4)
    pairs, ids, n = _with_sliding_pair(points, pairs, ids)
    assert np.all(tied_twice(pairs, ids, n)[-6:])
    assert trimmed_lattice(pairs, ids, n)[0] is None
    np.testing.assert_array_equal(sliding_povs(pairs, ids, n), [n - 2, n - 1])
    assert len(sliding_povs(pairs[:-6], ids[:-6], n)) == 0
    found = lattice_equalities(pairs, ids, n, 1)
    assert found.placed == len(points) and len(found.pairs)
    assert not found.kept[-6:].any() and not found.withdrawn[-6:].any()
    assert found.kept[:-6].all()
