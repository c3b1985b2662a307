"""The agent tells a looped dimension from flat ones by a chain of one change
closing on itself (core.naive.looped_dims)."""
import numpy as np
import pytest

from sensorispace_ros.core.naive.looped_dims import closed_chains, looped_dimensions
from sensorispace_ros.core.world import rotation_matrix


def _poses(count=7, turns=4):
    """Sensor poses on a lattice x ``turns`` orientations: (x, y, k)."""
    axis = np.arange(count) - count // 2
    gx, gy, k = np.meshgrid(axis, axis, np.arange(turns), indexing="ij")
    return np.column_stack([gx.ravel(), gy.ravel(), k.ravel()]).astype(float)


def _equality_set(poses, move):
    """Pairs (i, j): pose j is pose i moved by ``move`` (the POVs that see
    the same before and after the change), for the poses whose image is known."""
    index = {tuple(np.round(p, 9)): n for n, p in enumerate(poses)}
    pairs = [(i, index[key]) for i, p in enumerate(poses)
             if (key := tuple(np.round(move(p), 9))) in index]
    return np.asarray(pairs, dtype=int).reshape(-1, 2)


def _translate(d):
    return lambda p: np.array([p[0] + d[0], p[1] + d[1], p[2]])


def _turn(quarter_turns, center, turns=4):
    rot = rotation_matrix(quarter_turns * np.pi / 2)
    c = np.asarray(center, float)

    def move(p):
        xy = c + rot @ (p[:2] - c)
        return np.array([xy[0], xy[1], (p[2] + quarter_turns) % turns])
    return move


def _sets(poses, moves):
    pairs, ids = [], []
    for n, move in enumerate(moves):
        p = _equality_set(poses, move)
        pairs.append(p)
        ids.append(np.full(len(p), n))
    return np.concatenate(pairs), np.concatenate(ids)


def test_translations_never_close_a_chain():
    poses = _poses()
    pairs, ids = _sets(poses, [_translate((1, 0)), _translate((0, 2)), _translate((-1, 1))])
    assert len(pairs) > 50
    found = looped_dimensions(pairs, ids, space_dim=2)
    assert (found.looped_dims, found.flat_dims) == (0, 2)
    assert found.closing_sets == ()


def test_turns_close_their_chains_and_give_one_looped_dimension():
    poses = _poses()
    moves = [_translate((1, 0)), _turn(1, (0, 0)), _turn(2, (1, 1)), _translate((0, 1))]
    pairs, ids = _sets(poses, moves)
    found = looped_dimensions(pairs, ids, space_dim=3)
    assert (found.looped_dims, found.flat_dims) == (1, 2)
    assert set(found.closing_sets) == {1, 2}
    assert set(found.cycle_lengths) == {2, 4}      # a half turn swaps, a quarter turn needs four


def test_one_closing_set_is_not_enough_by_default():
    poses = _poses()
    pairs, ids = _sets(poses, [_turn(2, (0, 0)), _translate((1, 0))])
    assert looped_dimensions(pairs, ids, space_dim=3).looped_dims == 0
    assert looped_dimensions(pairs, ids, space_dim=3, min_closing_sets=1).looped_dims == 1


def test_closed_chains_counts_each_cycle_once_and_ignores_open_chains():
    pairs = np.array([[0, 1], [1, 2], [2, 0], [3, 4], [4, 3], [5, 6], [6, 7]])
    assert closed_chains(pairs) == {3: 1, 2: 1}


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="set_ids"):
        looped_dimensions(np.zeros((2, 2)), np.zeros(3), 2)
    with pytest.raises(ValueError, match="space_dim"):
        looped_dimensions(np.zeros((0, 2)), np.zeros(0), -1)
