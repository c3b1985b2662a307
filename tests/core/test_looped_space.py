"""Circular coordinates from persistent cohomology and the choice of the
looped one by the equality sets (core.looped_space)."""
import numpy as np
import pytest

from sensorispace_ros.core.looped_space import (betti_up_to_h2, circular_coordinates,
                                                circular_correlation, gap_count,
                                                looped_coordinate, synchronized_angle,
                                                synchronized_translations)
from sensorispace_ros.core.topology import euclidean_distances


def test_circular_correlation_is_one_for_a_shifted_or_reversed_angle_only():
    t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    assert circular_correlation(t + 1.0, t) == pytest.approx(1.0)
    assert circular_correlation(2.0 - t, t) == pytest.approx(1.0)
    noise = np.random.default_rng(0).uniform(0, 2 * np.pi, 90)
    assert circular_correlation(noise, t) < 0.2
    with pytest.raises(ValueError, match="angle samples"):
        circular_correlation(t, t[:3])


def test_the_coordinate_of_a_circle_goes_once_round_it():
    t = np.linspace(0, 2 * np.pi, 120, endpoint=False)
    points = np.column_stack([np.cos(t), np.sin(t)])
    angles, bars = circular_coordinates(euclidean_distances(points))
    assert circular_correlation(angles[0], t) > 0.999
    assert bars.shape == (1, 2) and bars[0, 1] > 5 * bars[0, 0]


def test_the_coordinate_on_landmarks_still_goes_once_round_the_circle():
    # more points than landmarks: ripser names the cocycle's vertices among all points
    t = np.random.default_rng(1).uniform(0, 2 * np.pi, 400)
    points = np.column_stack([np.cos(t), np.sin(t)])
    angles, _ = circular_coordinates(euclidean_distances(points), max_landmarks=60)
    assert circular_correlation(angles[0], t) > 0.98


def _ring_times_circle():
    """Points on (polar angle, heading) of a ring of radius 2 times a circle,
    with the heading turning with the polar angle as an arm's pose does."""
    polar, heading = np.meshgrid(np.linspace(0, 2 * np.pi, 24, endpoint=False),
                                 np.linspace(0, 2 * np.pi, 12, endpoint=False), indexing="ij")
    polar, heading = polar.ravel(), heading.ravel()
    relative = heading - polar           # a metric blind to turning the whole scene
    points = np.column_stack([2 * np.cos(polar), 2 * np.sin(polar),
                              np.cos(relative), np.sin(relative)])
    return points, polar, heading


def _turn_sets(polar, heading, steps=((3, 1), (5, 2), (0, 1), (7, 0))):
    """Equality sets of rigid changes: every pose's heading turned by the same
    step (b), its polar angle moved by a step (a) that differs from pose to pose
    unless the change is a turn about the ring's centre."""
    index = {(round(p, 6), round(h, 6)): n for n, (p, h) in
             enumerate(zip(polar % (2 * np.pi), heading % (2 * np.pi)))}
    dp, dh = 2 * np.pi / 24, 2 * np.pi / 12
    pairs, ids = [], []
    for s, (a, b) in enumerate(steps):
        for n, (p, h) in enumerate(zip(polar, heading)):
            shift = a + (n % 3)                 # the polar step varies from pose to pose
            key = (round((p + shift * dp) % (2 * np.pi), 6), round((h + b * dh) % (2 * np.pi), 6))
            if key in index:
                pairs.append((n, index[key]))
                ids.append(s)
    return np.asarray(pairs), np.asarray(ids)


def test_the_looped_coordinate_is_the_one_every_change_moves_uniformly():
    points, polar, heading = _ring_times_circle()
    angles, _ = circular_coordinates(euclidean_distances(points), n_loops=2)
    pairs, ids = _turn_sets(polar, heading)
    theta, coefficients, variance = looped_coordinate(angles, pairs, ids)
    # The equality sets single out the combination of the loops that is the heading.
    assert circular_correlation(theta, heading) > 0.99
    assert circular_correlation(theta, polar) < 0.5
    assert variance < 0.01 and np.abs(coefficients).max() >= 1
    with pytest.raises(ValueError, match="pairs"):
        looped_coordinate(angles, np.zeros((0, 2)), np.zeros(0))


def test_a_coordinate_bunched_on_part_of_the_circle_is_never_the_loop():
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    constant = np.zeros(60)
    pairs = np.column_stack([np.arange(59), np.arange(1, 60)])
    ids = np.zeros(59, dtype=int)
    # the constant agrees perfectly within the set; the loop's coordinate is chosen
    theta, coefficients, _ = looped_coordinate(np.vstack([constant, t]), pairs, ids)
    assert circular_correlation(theta, t) > 0.999 and coefficients[1] != 0
    assert looped_coordinate(constant[None], pairs, ids) is None


def test_synchronisation_averages_out_the_scatter_within_a_class_the_sets_join():
    """Eight orientation classes of 30 POVs each, a coordinate scattered by 0.4
    rad within each class; equality sets of translations (step 0 within a
    class) and of turns (one class to the next): the synchronised angle is the
    orientation up to an offset."""
    rng = np.random.default_rng(3)
    classes, per = 8, 30
    orientation = np.repeat(np.arange(classes) * 2 * np.pi / classes, per)
    theta0 = orientation + 0.5 + rng.normal(0.0, 0.4, len(orientation))
    index = np.arange(classes * per).reshape(classes, per)
    translation = np.column_stack([index[:, :-1].ravel(), index[:, 1:].ravel()])
    turn = np.column_stack([index[:-1, :].ravel(), index[1:, :].ravel()])
    pairs = np.vstack([translation, turn])
    ids = np.concatenate([np.zeros(len(translation), int), np.ones(len(turn), int)])
    assert circular_correlation(theta0, orientation) < 0.95
    theta = synchronized_angle(theta0, pairs, ids)
    # What is left is the least-squares drift along each chain of
    # translations (a step common to a set is all the sets fix).
    assert circular_correlation(theta, orientation) > 0.99

    def spread(angle):
        return np.mean(1 - np.abs(np.mean(np.exp(1j * angle).reshape(classes, per), axis=1)))

    assert spread(theta) < 0.05 * spread(theta0)


def test_synchronisation_keeps_the_coordinate_of_unpaired_povs_and_checks_its_arguments():
    theta0 = np.linspace(0.0, 6.0, 10)
    pairs, ids = np.array([[0, 1], [1, 2]]), np.array([0, 0])
    theta = synchronized_angle(theta0, pairs, ids)
    assert np.allclose(theta[3:], theta0[3:])
    assert np.allclose(synchronized_angle(theta0, np.zeros((0, 2)), np.zeros(0)), theta0)
    with pytest.raises(ValueError, match="set_ids"):
        synchronized_angle(theta0, pairs, ids[:1])
    with pytest.raises(ValueError, match="pairs"):
        synchronized_angle(theta0, np.array([[0, 10]]), np.array([0]))
    with pytest.raises(ValueError, match="anchor_weight"):
        synchronized_angle(theta0, pairs, ids, anchor_weight=0.0)


def test_gap_count_cuts_at_the_largest_ratio_among_long_lifetimes():
    assert gap_count([2.0, 1.8, 0.6, 0.5], 1.0) == (2, 3.0)
    assert gap_count([0.3, 0.2, 0.1], 1.0) == (0, 0.0)           # all within half a step
    assert gap_count([1.0, 0.9, 0.8, 0.7, 0.6], 1.0) == (0, 0.0)    # none stands out
    assert gap_count([1.2], 1.0) == (1, pytest.approx(2.4))      # against half a step


def _lattice_ring_times_octagon(spacing=1.0):
    """Lattice points of a ring (radii 1.5-3) times 8 orientations whose
    chord is the lattice step: the coarse sampling of a turning world."""
    axis = np.arange(-3.0, 3.0 + 1e-9, spacing)
    x, y = [v.ravel() for v in np.meshgrid(axis, axis)]
    keep = (np.hypot(x, y) >= 1.5) & (np.hypot(x, y) <= 3.0)
    a = np.arange(8) * 2 * np.pi / 8
    radius = spacing / (2 * np.sin(np.pi / 8))
    return np.array([[px, py, radius * np.cos(t), radius * np.sin(t)]
                     for px, py in zip(x[keep], y[keep]) for t in a])


def test_the_gap_rule_reads_a_coarse_ring_times_circle_where_the_scale_rule_reads_none():
    D = euclidean_distances(_lattice_ring_times_octagon())
    got = betti_up_to_h2(D, rule="gap")
    assert (got["betti0"], got["betti1"], got["betti2"]) == (1, 2, 1)
    scale = betti_up_to_h2(D)
    assert (scale["betti1"], scale["betti2"]) == (0, 0)
    with pytest.raises(ValueError, match="rule"):
        betti_up_to_h2(D, rule="largest")


def _lattice_sets(positions, steps):
    """One equality set per step: every pair of lattice points that step apart."""
    pairs, ids = [], []
    for k, step in enumerate(steps):
        for i, p in enumerate(positions):
            hit = np.flatnonzero(np.all(np.isclose(positions, p + step), axis=1))
            pairs.extend([(i, int(j)) for j in hit])
            ids.extend([k] * len(hit))
    return np.array(pairs), np.array(ids)


def test_translation_synchronisation_undoes_a_distortion_the_sets_pin():
    from sensorispace_ros.core.quality import affine_residual

    g = np.arange(6.0)
    truth = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    # A metric's embedding: bent, and stretched more on one side (the diagonal problem).
    bent = np.column_stack([truth[:, 0] ** 1.3, truth[:, 1] + 0.4 * np.sin(truth[:, 0])])
    pairs, ids = _lattice_sets(truth, [(2.0, 1.0), (-1.0, 3.0), (1.0, 1.0)])
    assert affine_residual(bent, truth) > 0.02
    assert affine_residual(synchronized_translations(bent, pairs, ids), truth) < 1e-6
    # A point in no pair (14, inside the lattice) is placed by its neighbours'
    # affine map; a set of one pair (0 -> 7: a wrong step) pins nothing.
    keep = ~np.any(pairs == 14, axis=1)
    loose = np.vstack([pairs[keep], [[0, 7]]])
    loose_ids = np.concatenate([ids[keep], [9]])
    out = synchronized_translations(bent, loose, loose_ids)
    others = np.arange(len(truth)) != 14
    assert affine_residual(out[others], truth[others]) < 1e-6
    assert affine_residual(out, truth) < 0.1 * affine_residual(bent, truth)
    with pytest.raises(ValueError, match="set_ids"):
        synchronized_translations(bent, pairs, ids[:3])
    with pytest.raises(ValueError, match="pairs"):
        synchronized_translations(bent, pairs + 100, ids)


def test_the_compensable_poses_of_the_rotation_world_read_ring_times_circle():
    """All 319 compensable poses of config/rotations.yaml (seed 0) on plane x
    circle: a ring times a circle, Betti numbers (1, 2, 1). On 200 greedy
    landmarks of them the 2-cycle (and a loop) is lost."""
    from shared import REPO

    from sensorispace_ros import config
    from sensorispace_ros.core.run_world import run_world
    from sensorispace_ros.evaluation.rotations import compensable_poses, pose_key

    world = run_world(config.load_config(REPO / "config" / "rotations.yaml"), 0)
    distance = euclidean_distances(pose_key(compensable_poses(world)[1]))
    assert len(distance) == 319
    truth = betti_up_to_h2(distance, rule="gap")
    assert (truth["betti0"], truth["betti1"], truth["betti2"]) == (1, 2, 1)
    coarse = betti_up_to_h2(distance, max_points=200, rule="gap")
    assert (coarse["betti1"], coarse["betti2"]) != (2, 1)
