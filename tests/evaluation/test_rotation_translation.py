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
