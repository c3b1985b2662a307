"""The POVs' lattice from equality sets alone (core/naive/lattice.py): each
set a displacement, its pairs POVs that displacement moves into each other."""
import numpy as np
import pytest

from sensorispace_ros.core.naive.lattice import lattice_coordinates, null_space_positions


def _sets(points: np.ndarray, n_sets: int, seed: int, max_pairs: int = 6):
    """Equality sets over integer ``points`` ``(P, d)``: per set a random
    displacement and up to ``max_pairs`` pairs it moves into each other."""
    rng = np.random.default_rng(seed)
    index = {tuple(p): i for i, p in enumerate(points.tolist())}
    pairs, ids = [], []
    while len(set(ids)) < n_sets:
        step = rng.integers(-4, 5, size=points.shape[1])
        if not step.any():
            continue
        moved = [(i, index[tuple(p)]) for i, p in enumerate((points + step).tolist())
                 if tuple(p) in index]
        if len(moved) < 2:
            continue
        chosen = rng.choice(len(moved), size=min(max_pairs, len(moved)), replace=False)
        set_id = len(set(ids))
        for c in chosen:
            pairs.append(moved[c])
            ids.append(set_id)
    return np.array(pairs), np.array(ids)


def _unimodular_map(ij: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """The integer affine map taking ``ij`` to ``truth`` (asserted exact and unimodular)."""
    design = np.c_[ij, np.ones(len(ij))]
    coef = np.round(np.linalg.lstsq(design, truth.astype(float), rcond=None)[0])
    np.testing.assert_array_equal(design @ coef, truth)
    assert abs(round(np.linalg.det(coef[:-1]))) == 1
    return coef


def _square_patch(seed: int, size: int = 14, keep: float = 0.8) -> np.ndarray:
    rng = np.random.default_rng(seed)
    grid = np.array([(i, j) for i in range(size) for j in range(size)])
    return grid[rng.random(len(grid)) < keep]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_square_patch_is_found_up_to_a_unimodular_map(seed):
    # Holes, an uneven edge, POVs in random order: every POV's coordinates are
    # the truth's under one integer map of determinant +-1 (a basis of the
    # same lattice), so a neighbour on the lattice is a neighbour here.
    points = _square_patch(seed)
    order = np.random.default_rng(seed).permutation(len(points))
    points = points[order]
    pairs, ids = _sets(points, 300, seed)
    lattice = lattice_coordinates(pairs, ids, len(points))
    assert lattice is not None and lattice.dim == 2
    assert lattice.placed.all() and lattice.residual < 1e-6
    coef = _unimodular_map(lattice.ij, points)
    # A reduced basis of the square lattice is its two unit steps.
    assert sorted(np.abs(coef[:-1]).sum(axis=1).tolist()) == [1.0, 1.0]


def test_a_line_is_found_in_one_dimension():
    points = np.array([[i] for i in range(40) if i % 7 != 3])
    pairs, ids = _sets(points, 60, 5)
    lattice = lattice_coordinates(pairs, ids, len(points))
    assert lattice is not None and lattice.dim == 1
    _unimodular_map(lattice.ij, points)


def test_a_pov_no_set_ties_to_the_others_is_not_placed():
    points = _square_patch(3)
    pairs, ids = _sets(points, 300, 3)
    alone = len(points)                   # a POV in no pair of any set
    lattice = lattice_coordinates(pairs, ids, alone + 1)
    assert lattice is not None
    assert not lattice.placed[alone] and lattice.placed[:alone].all()


def test_an_equality_that_contradicts_its_set_leaves_no_lattice():
    # One pair moved by another displacement than its set's: no positions
    # satisfy every set, the null space is the constant alone.
    points = _square_patch(4)
    pairs, ids = _sets(points, 300, 4)
    index = {tuple(p): i for i, p in enumerate(points.tolist())}
    first = pairs[ids == 0]
    step = points[first[0, 1]] - points[first[0, 0]]
    wrong = next((i, index[tuple(p + step + (1, 0))]) for i, p in enumerate(points.tolist())
                 if tuple(np.add(p, step) + (1, 0)) in index)
    pairs, ids = np.vstack([pairs, wrong]), np.append(ids, 0)
    assert null_space_positions(pairs, ids, len(points)) is None
    assert lattice_coordinates(pairs, ids, len(points)) is None


def test_too_few_sets_leave_no_lattice():
    points = _square_patch(5)
    pairs, ids = _sets(points, 2, 5, max_pairs=2)
    assert lattice_coordinates(pairs, ids, len(points)) is None


def test_two_lattices_offset_by_a_fraction_of_a_step_are_refused():
    # POVs on a lattice and on a copy shifted by a fraction of its step
    # (each set one displacement, some between the two copies): the sets fix
    # their positions, but no lattice holds them all with integer coordinates.
    patch = _square_patch(6, size=10, keep=1.0).astype(float)
    points = np.vstack([patch, patch + (0.3, 0.1)])
    index = {tuple(np.round(p, 6)): i for i, p in enumerate(points)}
    rng = np.random.default_rng(6)
    pairs, ids = [], []
    for set_id in range(300):
        step = rng.integers(-3, 4, size=2) + ((0.3, 0.1) if set_id % 3 == 0 else (0.0, 0.0))
        moved = [(i, index[key]) for i, p in enumerate(points)
                 if (key := tuple(np.round(p + step, 6))) in index]
        for c in rng.choice(len(moved), size=min(6, len(moved)), replace=False):
            pairs.append(moved[c])
            ids.append(set_id)
    pairs, ids = np.array(pairs), np.array(ids)
    assert null_space_positions(pairs, ids, len(points)) is not None
    assert lattice_coordinates(pairs, ids, len(points)) is None
    # Either copy alone is a lattice.
    alone = np.all(pairs < len(patch), axis=1)
    assert lattice_coordinates(pairs[alone], ids[alone], len(patch)) is not None


def test_three_dimensions_are_measured_and_not_reduced():
    cube = np.array([(i, j, k) for i in range(6) for j in range(6) for k in range(6)])
    pairs, ids = _sets(cube, 400, 7)
    positions = null_space_positions(pairs, ids, len(cube))
    assert positions is not None and positions.shape[1] == 3
    assert lattice_coordinates(pairs, ids, len(cube)) is None
