"""Persistent homology of a distance matrix and the Betti-number rule."""
import numpy as np
import pytest
from scipy.spatial.distance import pdist, squareform

from sensorispace_ros.core.topology import (K_SCALE, betti_numbers, euclidean_distances,
    persistence, topology_report)


def jittered_grid(half_width, step, seed):
    axis = np.arange(-half_width, half_width + step / 2, step)
    points = np.stack(np.meshgrid(axis, axis), -1).reshape(-1, 2)
    return points + np.random.default_rng(seed).uniform(-0.1, 0.1, points.shape) * step


def disc(radius=1.0, step=0.1, seed=0):
    points = jittered_grid(radius, step, seed)
    return points[np.hypot(*points.T) <= radius]


def annulus(inner=1.0, outer=3.0, step=0.25, seed=0):
    points = jittered_grid(outer, step, seed)
    radius = np.hypot(*points.T)
    return points[(radius >= inner) & (radius <= outer)]


def noisy_circle(n=200, noise=0.05, seed=0):
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0, 2 * np.pi, n)
    return np.stack([np.cos(angle), np.sin(angle)], 1) + rng.normal(0, noise, (n, 2))


def betti_of(points, **options):
    report = topology_report(euclidean_distances(points), **options)
    return report["betti0"], report["betti1"]


def test_a_disc_has_one_component_and_no_hole():
    points = disc()
    assert 250 < len(points) < 400
    assert betti_of(points) == (1, 0)


def test_an_annulus_has_one_component_and_one_hole():
    points = annulus()
    assert 250 < len(points) < 450
    assert betti_of(points) == (1, 1)


def test_two_separate_annuli_have_two_components_and_two_holes():
    ring = annulus(0.5, 1.0, step=0.1)
    points = np.vstack([ring, ring + [5.0, 0.0]])
    assert betti_of(points) == (2, 2)


def test_a_noisy_circle_has_one_hole():
    assert betti_of(noisy_circle()) == (1, 1)


def test_the_rule_reads_a_distance_matrix_alone_at_any_scale():
    """No positions, no dimension, no unit: a metric 1000 times larger, or the
    annulus bent into 3-D (a different metric, the same topology), reads the
    same, and the margin does not depend on the unit."""
    points = annulus()
    D = euclidean_distances(points)
    base = topology_report(D)
    scaled = topology_report(1000.0 * D)
    assert (scaled["betti0"], scaled["betti1"]) == (base["betti0"], base["betti1"]) == (1, 1)
    # ripser computes in single precision.
    assert scaled["margin"] == pytest.approx(base["margin"], rel=1e-6)
    assert scaled["threshold"] == pytest.approx(1000.0 * base["threshold"], rel=1e-6)
    x, y = points.T
    bent = np.stack([3 * np.cos(x / 3), 3 * np.sin(x / 3), y], 1)    # rolled onto a cylinder
    assert betti_of(bent) == (1, 1)
    city = squareform(pdist(points, "cityblock"))                  # not a Euclidean metric
    assert (topology_report(city)["betti0"], topology_report(city)["betti1"]) == (1, 1)


def test_the_margin_is_how_far_the_threshold_can_move():
    """Scaling k by just under the margin (either way) keeps both Betti
    numbers; scaling it by just over the margin changes one of them."""
    bars = persistence(euclidean_distances(annulus()))
    base = betti_numbers(bars)
    margin = base.margin
    assert margin > 1.2
    same = [betti_numbers(bars, K_SCALE * margin * 0.999),
            betti_numbers(bars, K_SCALE / (margin * 0.999))]
    assert all((b.betti0, b.betti1) == (base.betti0, base.betti1) for b in same)
    beyond = [betti_numbers(bars, K_SCALE * margin * 1.001),
              betti_numbers(bars, K_SCALE / (margin * 1.001))]
    assert any((b.betti0, b.betti1) != (base.betti0, base.betti1) for b in beyond)


def test_h0_has_the_one_infinite_bar_and_h1_lifetimes_are_sorted():
    report = topology_report(euclidean_distances(noisy_circle()))
    bars = persistence(euclidean_distances(noisy_circle()))
    assert np.sum(np.isinf(bars.h0[:, 1])) == 1
    top = report["h1_lifetimes_top3"]
    assert len(top) == 3 and top == sorted(top, reverse=True)
    assert top[0] > report["threshold"] > top[1]


def test_greedy_landmarks_cover_the_points_and_keep_the_topology():
    points = annulus()
    D = euclidean_distances(points)
    full = persistence(D, max_points=len(points))
    bars = persistence(D, max_points=250)
    assert len(full.landmarks) == len(points) and full.cover_radius == 0.0
    assert len(bars.landmarks) == 250 and len(set(bars.landmarks)) == 250
    # Every point within cover_radius of a landmark, landmarks at least that far apart.
    assert np.max(D[:, bars.landmarks].min(axis=1)) == pytest.approx(bars.cover_radius)
    sub = D[np.ix_(bars.landmarks, bars.landmarks)] + np.diag(np.full(250, np.inf))
    assert sub.min() >= bars.cover_radius * (1 - 1e-12)
    assert bars.cover_radius <= bars.scale
    # Stability: the hole's lifetime moves by at most 4 cover radii.
    hole_full = np.max(np.diff(full.h1, axis=1))
    hole = np.max(np.diff(bars.h1, axis=1))
    assert abs(hole - hole_full) <= 4 * bars.cover_radius
    assert (betti_numbers(bars).betti0, betti_numbers(bars).betti1) == (1, 1)


def test_the_landmarks_are_a_function_of_the_matrix():
    D = euclidean_distances(annulus(step=0.2))
    first, second = persistence(D, max_points=120), persistence(D, max_points=120)
    assert np.array_equal(first.landmarks, second.landmarks)
    assert np.array_equal(first.h1, second.h1)


@pytest.mark.parametrize("matrix, words", [
    (np.zeros((3, 2)), "square"),
    (np.zeros((1, 1)), "at least 2"),
    (np.array([[0.0, np.nan], [np.nan, 0.0]]), "NaN"),
    (np.array([[0.0, -1.0], [-1.0, 0.0]]), "negative"),
    (np.array([[1.0, 1.0], [1.0, 0.0]]), "diagonal"),
    (np.array([[0.0, 1.0], [2.0, 0.0]]), "symmetric"),
    (np.zeros((3, 3)), "coincide"),
])
def test_bad_matrices_are_refused_with_the_reason(matrix, words):
    with pytest.raises(ValueError, match=words):
        topology_report(matrix)


def test_bad_options_are_refused():
    D = euclidean_distances(noisy_circle(30))
    with pytest.raises(ValueError, match="max_points"):
        persistence(D, max_points=2)
    with pytest.raises(ValueError, match="k must be"):
        betti_numbers(persistence(D), k=0.0)
