import numpy as np
import pytest

from sensorispace_ros.core.paper.equality_sets import equality_sets_from_poses

SPACING = 0.2


@pytest.fixture
def positions():
    rng = np.random.default_rng(0)
    lattice = np.stack(np.meshgrid(np.arange(10), np.arange(10)), axis=-1).reshape(-1, 2)
    chosen = lattice[rng.choice(len(lattice), 60, replace=False)]
    # Sensor positions of compensations: off the origin, ~1e-4 jitter.
    return np.array([1.37, -0.55]) + SPACING * chosen + rng.normal(scale=1e-4, size=chosen.shape)


def test_every_pair_in_a_set_has_the_same_true_displacement(positions):
    pairs, set_ids = equality_sets_from_poses(positions, SPACING)
    displacement = positions[pairs[:, 1]] - positions[pairs[:, 0]]
    for set_id in np.unique(set_ids):
        members = displacement[set_ids == set_id]
        assert np.abs(members - members[0]).max() < 1e-3


def test_distinct_sets_have_distinct_displacements(positions):
    pairs, set_ids = equality_sets_from_poses(positions, SPACING)
    displacement = positions[pairs[:, 1]] - positions[pairs[:, 0]]
    representative = np.array([displacement[set_ids == s][0] for s in np.unique(set_ids)])
    gaps = np.linalg.norm(representative[:, None] - representative[None], axis=-1)
    np.fill_diagonal(gaps, np.inf)
    assert gaps.min() > 0.9 * SPACING
    assert np.array_equal(np.unique(set_ids), np.arange(len(representative)))


def test_each_unordered_pair_once_and_oriented_consistently(positions):
    pairs, set_ids = equality_sets_from_poses(positions, SPACING)
    n = len(positions)
    assert len(pairs) == len(set_ids) == n * (n - 1) // 2
    assert np.all(pairs[:, 0] != pairs[:, 1])
    assert len({tuple(sorted(p)) for p in pairs.tolist()}) == len(pairs)
    step = np.rint((positions[pairs[:, 1]] - positions[pairs[:, 0]]) / SPACING)
    assert np.all((step[:, 0] > 0) | ((step[:, 0] == 0) & (step[:, 1] > 0)))


def test_opposite_displacements_share_a_set():
    positions = SPACING * np.array([[0, 0], [1, 0], [3, 0], [2, 0]], dtype=float)
    pairs, set_ids = equality_sets_from_poses(positions, SPACING)
    unit = [k for k, (i, j) in enumerate(pairs.tolist())
            if abs(positions[j, 0] - positions[i, 0]) == pytest.approx(SPACING)]
    # Three pairs one cell apart: (0,1), (3,2) and (1,3), whatever their index order.
    assert len(unit) == 3
    assert len(set(set_ids[unit])) == 1
    for k in unit:
        i, j = pairs[k]
        assert positions[j, 0] > positions[i, 0]


def test_single_position_gives_no_pair():
    pairs, set_ids = equality_sets_from_poses(np.zeros((1, 2)), SPACING)
    assert pairs.shape == (0, 2) and set_ids.shape == (0,)


def test_position_off_the_lattice_belongs_to_no_pair(positions):
    # Like the initial POV of simulation 1: half a cell off the grid, first in the list.
    off = positions[0] + 0.5 * SPACING
    pairs, set_ids = equality_sets_from_poses(np.vstack([off, positions]), SPACING)
    assert not np.any(pairs == 0)
    n = len(positions)
    assert len(pairs) == n * (n - 1) // 2
    displacement = positions[pairs[:, 1] - 1] - positions[pairs[:, 0] - 1]
    for set_id in np.unique(set_ids):
        members = displacement[set_ids == set_id]
        assert np.abs(members - members[0]).max() < 1e-3


@pytest.mark.parametrize("args, name", [
    ((np.zeros((3, 3)), SPACING), "true_positions"), ((np.zeros((3, 2)), 0.0), "spacing")])
def test_rejects_bad_arguments(args, name):
    with pytest.raises(ValueError, match=name):
        equality_sets_from_poses(*args)
