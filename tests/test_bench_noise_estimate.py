"""bench/noise_estimate.py reads each case against its true sd (Laplace of
scale b: sd b sqrt(2)) and tells the pooled estimate from the larger spread."""
import sys

import numpy as np
import pytest

from shared import REPO
sys.path.insert(0, str(REPO / "bench"))
sys.path.insert(0, str(REPO / "tests" / "core"))

import noise_estimate  # noqa: E402
from imperfect_bodies import SmoothBody  # noqa: E402

CENTER = np.array([0.3, -0.7])


@pytest.mark.parametrize("kind", ["noise", "laplace"])
def test_each_case_is_read_against_its_true_sd(kind):
    case = noise_estimate.measure(SmoothBody, CENTER, kind, 1e-3, draws=40)
    assert abs(case["estimate / true"]["mean"] - 1.0) < 0.1
    assert case["estimate / true"]["p2.5"] <= case["estimate / true"]["mean"] \
        <= case["estimate / true"]["p97.5"]
    assert case["pooled share"] > 0.8


def test_the_larger_spread_is_the_wider_of_the_two_readings():
    case = noise_estimate.measure(SmoothBody, CENTER, "noise", 1e-3, draws=60)
    assert case["larger robust spread / true"]["sd"] > case["estimate / true"]["sd"]
    assert case["larger robust spread / true"]["mean"] > case["estimate / true"]["mean"]
