"""Curvilinear Component Analysis estimator."""
import numpy as np
import pytest
from numpy_bits import assert_numpy_bits
from scipy.spatial import procrustes
from scipy.spatial.distance import pdist, squareform
from sklearn.base import clone
from sklearn.manifold import trustworthiness

from sensorispace_ros.core import cca as cca_module
from sensorispace_ros.core.cca import CCA, cca_stress, classical_mds


@pytest.fixture(scope="module")
def jittered_grid():
    rng = np.random.default_rng(0)
    grid = np.stack(np.meshgrid(np.arange(20.0), np.arange(20.0)), -1).reshape(-1, 2) * 0.1
    return grid + rng.uniform(-0.02, 0.02, grid.shape)


@pytest.fixture(scope="module")
def curled_sheet():
    """A sheet rolled 3/4 of a turn: its 2-D truth is (arc angle, height)."""
    rng = np.random.default_rng(1)
    u = rng.uniform(0, 1.5 * np.pi, 500)
    v = rng.uniform(0, 3, 500)
    return np.stack([np.cos(u), np.sin(u), v], -1), np.stack([u, v], -1)


@pytest.mark.parametrize("init", ["random", "mds"])
def test_recovers_a_flat_grid_up_to_similarity(jittered_grid, init):
    D = squareform(pdist(jittered_grid))
    Y = CCA(2, init=init, n_epochs=15, random_state=3).fit_transform(D)
    _, _, disparity = procrustes(jittered_grid, Y)
    assert disparity < 1e-6


def test_random_start_is_far_from_the_answer_before_training(jittered_grid):
    # Guards the test above: a random start is not already a similarity image.
    D = squareform(pdist(jittered_grid))
    Y = CCA(2, init="random", n_epochs=1, alpha0=1e-9, random_state=3).fit_transform(D)
    assert procrustes(jittered_grid, Y)[2] > 0.5


def test_unrolls_a_curled_sheet_better_than_mds(curled_sheet):
    X, truth = curled_sheet
    Y = CCA(2, metric="euclidean", n_epochs=20, random_state=0).fit_transform(X)
    mds = classical_mds(squareform(pdist(X)), 2)
    t_cca = trustworthiness(truth, Y, n_neighbors=5)
    t_mds = trustworthiness(truth, mds, n_neighbors=5)
    assert t_cca > 0.995
    assert t_cca > t_mds + 0.02


def test_classical_mds_is_exact_on_euclidean_points(jittered_grid):
    Y = classical_mds(squareform(pdist(jittered_grid)), 2)
    np.testing.assert_allclose(pdist(Y), pdist(jittered_grid), atol=1e-10)


def test_seeded_runs_repeat_and_seeds_differ(jittered_grid):
    D = squareform(pdist(jittered_grid[:100]))
    a = CCA(2, init="random", n_epochs=3, random_state=5).fit_transform(D)
    b = CCA(2, init="random", n_epochs=3, random_state=5).fit_transform(D)
    c = CCA(2, init="random", n_epochs=3, random_state=6).fit_transform(D)
    g = CCA(2, init="random", n_epochs=3,
            random_state=np.random.default_rng(5)).fit_transform(D)
    assert np.array_equal(a, b)
    assert np.array_equal(a, g)
    assert not np.allclose(a, c)


def test_euclidean_metric_equals_precomputed(curled_sheet):
    X = curled_sheet[0][:120]
    a = CCA(3, metric="euclidean", n_epochs=3, random_state=2).fit_transform(X)
    b = CCA(3, n_epochs=3, random_state=2).fit_transform(squareform(pdist(X)))
    assert np.array_equal(a, b)


def test_fitted_attributes_and_warm_start(jittered_grid):
    D = squareform(pdist(jittered_grid[:60]))
    est = CCA(2, n_epochs=4, random_state=0).fit(D)
    assert est.embedding_.shape == (60, 2)
    assert est.n_iter_ == 4
    assert est.stress_ >= 0
    assert est.lambda0_ == pytest.approx(3 * np.std(classical_mds(D, 2), axis=0).max())
    # A warm start at the answer stays there: every dx == dy, the rule is a no-op.
    Y = CCA(2, n_epochs=2, random_state=0).fit_transform(D, init=jittered_grid[:60])
    np.testing.assert_allclose(Y, jittered_grid[:60], atol=1e-12)
    assert clone(est).get_params()["n_epochs"] == 4


def test_stress_drops_from_a_bad_start(jittered_grid):
    D = squareform(pdist(jittered_grid[:80]))
    start = CCA(2, init="random", n_epochs=1, alpha0=1e-9, random_state=1).fit_transform(D)
    end = CCA(2, init="random", n_epochs=10, random_state=1).fit_transform(D)
    # Compared at one radius covering the whole grid (stress_ uses the final, tiny one).
    assert cca_stress(D, end, 1.0) < 1e-2 * cca_stress(D, start, 1.0)


@pytest.mark.parametrize("X, word", [
    (np.zeros((3, 4)), "square"),
    (np.array([[0.0, 1.0], [2.0, 0.0]]), "symmetric"),
    (np.array([[0.0, np.nan], [np.nan, 0.0]]), "NaN"),
    (np.array([[0.0, -1.0], [-1.0, 0.0]]), "negative"),
    (np.zeros((1, 1)), "at least 2"),
])
def test_bad_distance_matrices_raise(X, word):
    with pytest.raises(ValueError, match=word):
        CCA().fit(X)


@pytest.mark.parametrize("params, word", [
    ({"n_components": 0}, "n_components"),
    ({"metric": "cosine"}, "metric"),
    ({"n_epochs": 0}, "n_epochs"),
    ({"alpha0": -1.0}, "alpha0"),
    ({"lambda0": 0.0}, "lambda0"),
    ({"init": "pca"}, "init"),
    ({"init": np.zeros((3, 2))}, "init array"),
    ({"random_state": "seed"}, "random_state"),
    ({"kernel": "cython"}, "kernel"),
])
def test_bad_parameters_raise(params, word):
    D = squareform(pdist(np.random.default_rng(0).random((5, 2))))
    with pytest.raises(ValueError, match=word):
        CCA(**params).fit(D)


@pytest.mark.parametrize("n_components", [1, 2, 3])
@pytest.mark.numpy_bits
def test_step_loop_transcription_equals_the_numpy_loop(curled_sheet, monkeypatch, n_components):
    """The compiled kernel's source, run as plain Python, gives the NumPy
    loop's bits: same operations in the same order (checked without numba)."""
    X = curled_sheet[0][:40]
    reference = CCA(n_components, metric="euclidean", n_epochs=3, random_state=4,
                    kernel="numpy").fit_transform(X)
    monkeypatch.setattr(cca_module, "_cca_steps_compiled", cca_module._cca_steps)
    transcribed = CCA(n_components, metric="euclidean", n_epochs=3, random_state=4,
                      kernel="numba").fit_transform(X)
    assert_numpy_bits(transcribed, reference, rtol=1e-12, atol=1e-12)
    # and the steps moved the points (a kernel doing nothing would fail here)
    shorter = CCA(n_components, metric="euclidean", n_epochs=1, random_state=4,
                  kernel="numba").fit_transform(X)
    assert not np.array_equal(transcribed, shorter)


@pytest.mark.skipif(not cca_module.numba_available(), reason="numba is not installed")
@pytest.mark.numpy_bits
@pytest.mark.parametrize("n_components", [2, 3])
def test_compiled_kernel_is_bitwise_the_numpy_loop(curled_sheet, n_components):
    X = curled_sheet[0]
    numpy_loop = CCA(n_components, metric="euclidean", n_epochs=5, random_state=2,
                     kernel="numpy").fit_transform(X)
    compiled = CCA(n_components, metric="euclidean", n_epochs=5, random_state=2,
                   kernel="numba").fit_transform(X)
    assert_numpy_bits(compiled, numpy_loop, rtol=1e-12, atol=1e-12)


def test_numba_kernel_without_numba_raises(monkeypatch):
    monkeypatch.setattr(cca_module, "_cca_steps_compiled", None)
    D = squareform(pdist(np.random.default_rng(0).random((5, 2))))
    with pytest.raises(ValueError, match="numba"):
        CCA(kernel="numba").fit(D)
    assert CCA(kernel="auto", n_epochs=2, random_state=0).fit_transform(D).shape == (5, 2)
