"""bench/brief_walks.py's distance between two walks' samples, on the torus."""
import sys

import numpy as np

from shared import REPO
sys.path.insert(0, str(REPO))

from bench import brief_walks  # noqa: E402


def test_samples_a_turn_apart_are_the_same_samples():
    loop = np.stack([np.linspace(-3.0, 3.0, 50), np.zeros(50), np.full(50, 1.0)], axis=1)
    assert brief_walks.torus_hausdorff(loop, loop + 2.0 * np.pi) < 1e-12


def test_the_distance_is_the_farthest_sample_from_the_other_set():
    loop = np.stack([np.linspace(0.0, 1.0, 11), np.zeros(11)], axis=1)
    moved = loop.copy()
    moved[4, 1] = 0.3                       # one sample off the other loop
    assert np.isclose(brief_walks.torus_hausdorff(loop, moved), 0.3)
    # Across the seam: -pi + 0.1 and pi - 0.1 are 0.2 apart, not 2 pi - 0.2.
    a, b = np.array([[np.pi - 0.1, 0.0]]), np.array([[-np.pi + 0.1, 0.0]])
    assert np.isclose(brief_walks.torus_hausdorff(a, b), 0.2)
