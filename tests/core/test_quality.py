"""Quality numbers of a representation."""
import json

import numpy as np
import pytest

from sensorispace_ros.core.quality import (affine_residual, continuity, quality_report, spearman,
    trustworthiness)


@pytest.fixture(scope="module")
def grid():
    g = np.stack(np.meshgrid(np.linspace(-1, 1, 15), np.linspace(-1, 1, 15)), -1).reshape(-1, 2)
    return g + np.random.default_rng(0).uniform(-0.01, 0.01, g.shape)


def similarity(points, angle=0.7, scale=3.0, shift=(5.0, -2.0)):
    c, s = np.cos(angle), np.sin(angle)
    return scale * points @ np.array([[c, -s], [s, c]]) + np.array(shift)


def test_affine_residual_zero_for_affine_images(grid):
    rng = np.random.default_rng(1)
    for _ in range(3):
        A = rng.normal(size=(2, 2))
        assert affine_residual(grid @ A + rng.normal(size=2), grid) < 1e-12
    # A 3-D embedding that is an affine image of the plane works too.
    B = rng.normal(size=(2, 3))
    assert affine_residual(grid @ B + 1.0, grid) < 1e-12


def test_affine_residual_large_for_a_nonlinear_warp(grid):
    x, y = grid.T
    warped = np.stack([np.sin(2 * x) + y ** 2, y + np.cos(3 * x)], -1)
    assert affine_residual(warped, grid) > 0.1
    # Pure noise explains nothing: close to 1.
    noise = np.random.default_rng(2).normal(size=grid.shape)
    assert affine_residual(noise, grid) > 0.9


def test_similarity_is_perfect(grid):
    Y = similarity(grid)
    assert trustworthiness(grid, Y) == pytest.approx(1.0)
    assert continuity(grid, Y) == pytest.approx(1.0)
    assert spearman(grid, Y) == pytest.approx(1.0)


def test_scrambled_neighbours_lower_trust_and_continuity(grid):
    Y = similarity(grid).copy()
    rng = np.random.default_rng(3)
    picked = rng.choice(len(grid), size=40, replace=False)
    Y[picked] = Y[rng.permutation(picked)]
    assert trustworthiness(grid, Y) < 0.98
    assert continuity(grid, Y) < 0.98
    assert spearman(grid, Y) < 0.99


def test_continuity_is_trustworthiness_with_roles_swapped(grid):
    # Folding the plane onto a line keeps neighbours (continuity) but brings
    # far points together (trustworthiness suffers) - the two differ.
    folded = np.abs(grid[:, :1])
    assert continuity(grid, folded) == pytest.approx(trustworthiness(folded, grid))
    assert continuity(grid, folded) != pytest.approx(trustworthiness(grid, folded))


def test_report_is_json_stable_floats(grid):
    report = quality_report(similarity(grid) + 1e-3 * np.sin(7 * grid), grid)
    assert set(report) == {"trustworthiness", "continuity", "spearman", "affine_residual"}
    assert all(type(v) is float for v in report.values())
    assert json.loads(json.dumps(report)) == report
    assert all(float(f"{v:.12g}") == v for v in report.values())
    assert 0.99 < report["trustworthiness"] < 1.0


def test_report_of_few_points_ranks_the_neighbourhood_they_allow(grid):
    # Six POVs (a run that found few) cannot rank 5 neighbours; 2 they can:
    # an embedding that swaps two far points loses trustworthiness there.
    few = grid[:: len(grid) // 6][:6]
    assert quality_report(few, few)["trustworthiness"] == 1.0
    swapped = few.copy()
    swapped[[0, -1]] = swapped[[-1, 0]]
    assert quality_report(swapped, few)["trustworthiness"] == pytest.approx(
        trustworthiness(few, swapped, n_neighbors=2))
    assert quality_report(swapped, few)["trustworthiness"] < 1.0


@pytest.mark.parametrize("call, word", [
    (lambda g: affine_residual(g[:10], g), "points"),
    (lambda g: trustworthiness(g, g, n_neighbors=0), "n_neighbors"),
    (lambda g: spearman(g[:, 0], g), "shape"),
    (lambda g: continuity(g, np.full_like(g, np.nan)), "NaN"),
    (lambda g: affine_residual(g, np.zeros_like(g)), "all equal"),
])
def test_bad_input_raises(grid, call, word):
    with pytest.raises(ValueError, match=word):
        call(grid)
