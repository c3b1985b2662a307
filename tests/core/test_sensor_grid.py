"""Ground truth of the external grid: diagonal ratio and missed ring positions."""
import numpy as np
import pytest

from sensorispace_ros.core.sensor_grid import (WORKING_RING, diagonal_ratio, lattice_origin,
    missed_in_ring, offset_pairs, ring_positions)
from sensorispace_ros.core.topology import euclidean_distances

STEP = 12 / 61                                   # the paper grid's step


def lattice(origin, half_width=4.0, step=STEP):
    n = int(np.ceil(half_width / step))
    k = np.arange(-n, n + 1)
    return np.asarray(origin) + step * np.stack(np.meshgrid(k, k), -1).reshape(-1, 2)


def in_ring(points, ring=WORKING_RING):
    radius = np.hypot(*points.T)
    return points[(radius >= ring[0]) & (radius <= ring[1])]


def test_offset_pairs_find_the_diagonal_neighbours():
    points = lattice((0.0, 0.0), half_width=0.5, step=0.25)   # 5 x 5
    rising = offset_pairs(points, 0.25, (1, 1))
    assert len(rising) == 16
    assert np.allclose(points[rising[:, 1]] - points[rising[:, 0]], [0.25, 0.25])
    falling = offset_pairs(points, 0.25, (1, -1))
    assert np.allclose(points[falling[:, 1]] - points[falling[:, 0]], [0.25, -0.25])


def test_diagonal_ratio_is_one_for_the_plane_and_the_shear_ratio_for_a_shear():
    points = in_ring(lattice((0.1, -0.05)))
    assert diagonal_ratio(euclidean_distances(points), points, STEP) == pytest.approx(1.0)
    # A shear keeps opposite sides equal but not the diagonals (paper Fig. 13).
    sheared = points @ np.array([[1.0, 0.0], [0.2, 1.0]])
    expected = np.hypot(1.2, 1.0) / np.hypot(0.8, 1.0)
    assert diagonal_ratio(euclidean_distances(sheared), points, STEP) == pytest.approx(expected)


def test_diagonal_ratio_without_diagonals_is_nan():
    row = np.stack([np.arange(5) * STEP, np.zeros(5)], 1)
    assert np.isnan(diagonal_ratio(euclidean_distances(row), row, STEP))


def test_ring_positions_are_the_lattice_points_of_the_ring():
    origin = np.array([0.37, -0.81])
    points = in_ring(lattice(origin))
    nodes = ring_positions(points, STEP)
    assert len(nodes) == len(points)
    assert np.allclose(np.sort(nodes, axis=0), np.sort(points, axis=0))


def test_missed_in_ring_finds_the_removed_positions_and_ignores_an_off_lattice_one():
    points = in_ring(lattice((0.37, -0.81)))
    removed = np.array([5, 100, 300])
    kept = np.delete(points, removed, axis=0)
    # The initial POV of a strategy can lie half a step off the lattice the
    # others follow; it neither covers a ring position nor moves the lattice.
    kept = np.vstack([points[7] + STEP / 2, kept])
    missed = missed_in_ring(kept, STEP)
    assert np.allclose(np.sort(missed, axis=0), np.sort(points[removed], axis=0))
    assert np.allclose(lattice_origin(kept, STEP) - points[0],
                       STEP * np.round((lattice_origin(kept, STEP) - points[0]) / STEP))
    assert len(missed_in_ring(points, STEP)) == 0


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="positions"):
        missed_in_ring(np.zeros((3, 3)), STEP)
    with pytest.raises(ValueError, match="spacing"):
        missed_in_ring(np.zeros((3, 2)), 0.0)
    with pytest.raises(ValueError, match="ring"):
        ring_positions(np.zeros((3, 2)), STEP, ring=(3.0, 1.0))
    with pytest.raises(ValueError, match="distance"):
        diagonal_ratio(np.zeros((2, 2)), np.zeros((3, 2)), STEP)
