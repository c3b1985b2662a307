"""The flat embedding of the translations of a turning world, one
orientation class at a time (``evaluation.rotations.translation_numbers``),
and the trustworthiness that lets a lattice's tied neighbours be."""
from __future__ import annotations

import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.core import quality
from sensorispace_ros.core.paper.equality_sets import equality_sets_by_orientation
from sensorispace_ros.core.topology import euclidean_distances
from sensorispace_ros.evaluation.rotations import (orientation_classes, tied_trustworthiness,
                                                   translation_numbers)


def test_orientation_classes_split_the_circle_at_its_gaps_and_keep_a_class_across_zero():
    angle = np.array([6.27, 0.01, 0.02, 1.0, 1.01, 3.0, 6.28])
    labels = orientation_classes(angle)
    assert labels[0] == labels[1] == labels[2] == labels[6]
    assert labels[3] == labels[4] != labels[0] and labels[5] not in (labels[0], labels[3])
    assert len(set(labels)) == 3
    assert np.all(orientation_classes(np.full(5, 2.0)) == 0)


def test_tied_trustworthiness_forgives_only_ties():
    axis = np.arange(8.0)
    lattice = np.column_stack([v.ravel() for v in np.meshgrid(axis, axis)])
    nudged = lattice + np.random.default_rng(0).normal(0.0, 1e-4, lattice.shape)
    # scikit-learn's ranks break the lattice's ties by index: a copy nudged by
    # 1e-4 of a step loses there, not here
    assert quality.trustworthiness(lattice, nudged, n_neighbors=5) < 0.999
    assert tied_trustworthiness(lattice, nudged, 5) == 1.0
    sheared = lattice @ np.array([[1.0, 0.0], [0.0, 2.5]])   # an affine image reorders neighbours
    assert tied_trustworthiness(lattice, sheared, 5) < 0.99
    rng = np.random.default_rng(1)
    cloud = rng.normal(size=(60, 2))
    noisy = cloud + rng.normal(0.0, 0.3, cloud.shape)
    assert tied_trustworthiness(cloud, noisy, 5) == pytest.approx(
        quality.trustworthiness(cloud, noisy, n_neighbors=5))
    with pytest.raises(ValueError, match="n_neighbors"):
        tied_trustworthiness(cloud, noisy, 40)


def test_each_orientation_class_gets_a_flat_embedding_of_its_translations():
    """Three orientations of an annulus of lattice positions; the metric is
    the Euclidean one of the positions, each orientation class far from the
    others; the angle coordinate gives the classes."""
    axis = np.arange(-4.0, 4.5, 1.0)
    x, y = [v.ravel() for v in np.meshgrid(axis, axis)]
    keep = (np.hypot(x, y) > 1.5) & (np.hypot(x, y) < 4.2)
    turns = np.array([0.0, 2.0, 4.0])
    poses = np.array([[px, py, t] for t in turns for px, py in zip(x[keep], y[keep])])
    points = np.column_stack([poses[:, :2], 30.0 * np.cos(poses[:, 2]),
                              30.0 * np.sin(poses[:, 2])])
    pairs, set_ids = equality_sets_by_orientation(poses, 1.0)
    cfg = config.load_config(None, {"representation.regularization.iterations": 2,
                                     "representation.cca.n_epochs": 10})
    got = translation_numbers(euclidean_distances(points), poses, poses[:, 2] + 0.3,
                              pairs, set_ids, cfg, seed=0)
    assert got["rotation.translation.classes"] == 3
    assert got["rotation.translation.class_povs_min"] == int(keep.sum())
    assert got["rotation.translation.affine_residual_max"] < 1e-3
    assert got["rotation.translation.trustworthiness_min"] > 0.999


def _turned_pair_of_lattices():
    """A 5 x 5 lattice at orientation A and its image turned by 90 degrees and
    shifted at orientation B; class B in a frame of its own (an affine map)."""
    from sensorispace_ros.core.world import rotation_matrix

    g = np.arange(5.0)
    lattice = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    turned = lattice @ rotation_matrix(np.pi / 2).T + np.array([7.0, -2.0])
    frame = np.array([[1.5, 0.4], [-0.2, 0.8]])
    flat = np.vstack([lattice, turned @ frame.T + np.array([3.0, 1.0])])
    classes = np.repeat([0, 1], 25)
    return lattice, turned, flat, classes


def test_a_pov_no_translation_places_is_placed_through_a_turn_exactly():
    from sensorispace_ros.evaluation.rotations import place_by_turns

    lattice, turned, flat, classes = _turned_pair_of_lattices()
    # One set: the turn taking every A pose to its B image.
    pairs = np.column_stack([np.arange(25), 25 + np.arange(25)])
    set_ids = np.zeros(25, dtype=int)
    placed = np.ones(50, dtype=bool)
    placed[25 + 12] = False
    lost = flat.copy()
    lost[25 + 12] = [40.0, -40.0]          # where a metric might have put it
    out, done = place_by_turns(lost, placed, classes, pairs, set_ids)
    truth = np.vstack([lattice, turned])
    assert done.all()
    assert quality.affine_residual(lost[25:], truth[25:]) > 0.1
    assert quality.affine_residual(out[25:], truth[25:]) < 1e-12
    # With no placed pair of the set but its own, nothing tells where it lies.
    alone = np.zeros(50, dtype=bool)
    alone[[12, 25 + 3]] = True
    _, none = place_by_turns(lost, alone, classes, pairs, set_ids)
    assert not none[25 + 12]


def test_translation_numbers_place_the_parts_the_sets_leave_loose():
    """Class B's translation pairs split it in two parts (no pair between
    them): the sets fix each part's shape, not where one lies against the
    other; the turn set to class A places the smaller part."""
    lattice, turned, flat, classes = _turned_pair_of_lattices()
    poses = np.column_stack([np.vstack([lattice, turned]), np.repeat([0.0, np.pi / 2], 25)])
    steps = [(1.0, 0.0), (0.0, 1.0)]
    pairs, set_ids = [], []
    for k, step in enumerate(steps):             # translations: in world coordinates
        for i in range(50):
            for j in range(50):
                same = classes[i] == classes[j]
                apart = np.allclose(poses[j, :2] - poses[i, :2], step)
                lower_b = classes[i] == 1 and (poses[i, 1] < -0.5) != (poses[j, 1] < -0.5)
                if same and apart and not lower_b:
                    pairs.append((i, j))
                    set_ids.append(k)
    pairs += [(i, 25 + i) for i in range(25)]
    set_ids += [2] * 25
    distance = euclidean_distances(np.column_stack([flat + 0.2 * np.sin(flat), 20.0 * classes]))
    cfg = config.load_config(None, {"representation.regularization.iterations": 2,
                                     "representation.cca.n_epochs": 10})
    got = translation_numbers(distance, poses, poses[:, 2], np.array(pairs),
                              np.array(set_ids), cfg, seed=0)
    assert got["rotation.translation.classes"] == 2
    assert got["rotation.translation.unpaired_povs"] > 0
    assert got["rotation.translation.unplaced_povs"] == 0
    assert got["rotation.translation.affine_residual_max"] < 1e-6
