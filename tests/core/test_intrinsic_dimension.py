"""The Levina-Bickel estimate on clouds of known dimension, from distances only."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from sensorispace_ros.core.intrinsic_dimension import mle_dimension


def _circle(rng, n=600):
    t = rng.uniform(0, 2 * np.pi, n)
    return np.c_[np.cos(t), np.sin(t)]


def _lattice_ring(n=40):
    g = np.linspace(-3, 3, n)
    X = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    radius = np.hypot(*X.T)
    return X[(radius >= 1) & (radius <= 3)]


CLOUDS = {
    "circle in the plane": (lambda rng: _circle(rng), 1),
    "helix in 3-D": (lambda rng: (lambda t: np.c_[np.cos(t), np.sin(t), 0.2 * t])(
        rng.uniform(0, 12, 800)), 1),
    "uniform square": (lambda rng: rng.uniform(-1, 1, (700, 2)), 2),
    "square lattice ring": (lambda rng: _lattice_ring(), 2),
    "curved sheet in 3-D": (lambda rng: (lambda X: np.c_[X, np.sin(2 * X[:, 0])])(
        rng.uniform(-1, 1, (800, 2))), 2),
    "uniform cube": (lambda rng: rng.uniform(-1, 1, (900, 3)), 3),
    "Gaussian in 4-D": (lambda rng: rng.normal(size=(1200, 4)), 4),
}


@pytest.mark.parametrize("name", CLOUDS)
def test_the_estimate_rounds_to_the_dimension(name):
    make, dimension = CLOUDS[name]
    X = make(np.random.default_rng(0))
    assert round(mle_dimension(cdist(X, X))) == dimension


def test_the_estimate_ignores_the_scale_and_the_norm():
    X = _lattice_ring()
    euclidean = mle_dimension(cdist(X, X))
    assert mle_dimension(1e-3 * cdist(X, X)) == pytest.approx(euclidean, rel=1e-9)
    assert round(mle_dimension(cdist(X, X, "chebyshev"))) == 2
    assert round(mle_dimension(cdist(X, X, "cityblock"))) == 2


def test_a_point_found_twice_counts_once_and_close_twins_do_not_change_the_answer():
    rng = np.random.default_rng(1)
    X = rng.uniform(-1, 1, (700, 2))
    base = mle_dimension(cdist(X, X))
    spacing = np.median(np.sort(cdist(X, X), axis=1)[:, 1])
    doubled = np.vstack([X, X[:200], X[:150] + 1e-6 * spacing * rng.normal(size=(150, 2))])
    assert mle_dimension(cdist(doubled, doubled)) == pytest.approx(base, rel=1e-12)
    twins = np.vstack([X, X[:70] + 0.01 * spacing * rng.normal(size=(70, 2))])
    assert mle_dimension(cdist(twins, twins)) != pytest.approx(base, rel=1e-6)
    assert round(mle_dimension(cdist(twins, twins))) == 2


def test_bad_input_is_refused_with_the_reason():
    X = np.random.default_rng(2).uniform(size=(50, 2))
    with pytest.raises(ValueError, match="more than k_max"):
        mle_dimension(cdist(X, X))
    with pytest.raises(ValueError, match="square"):
        mle_dimension(np.zeros((3, 4)))
    with pytest.raises(ValueError, match="non-negative"):
        mle_dimension(-np.ones((100, 100)))
    with pytest.raises(ValueError, match="k_min"):
        mle_dimension(np.ones((100, 100)), k_range=(1, 5))
