"""Curvilinear Component Analysis estimator."""
import doctest
import warnings

import numpy as np
import pytest
from numpy_bits import assert_numpy_bits
from scipy import sparse
from scipy.spatial import procrustes
from scipy.spatial.distance import pdist, squareform
from sklearn.base import clone
from sklearn.manifold import trustworthiness
from sklearn.utils.estimator_checks import estimator_checks_generator

from sensorispace_ros.core import cca as cca_module
from sensorispace_ros.core.cca import CCA, cca_stress, check_distance_matrix, classical_mds

PRE = {"metric": "precomputed"}


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
    Y = CCA(2, **PRE, init=init, n_epochs=15, random_state=3).fit_transform(D)
    _, _, disparity = procrustes(jittered_grid, Y)
    assert disparity < 1e-6


def test_random_start_is_far_from_the_answer_before_training(jittered_grid):
    # Guards the test above: a random start is not already a similarity image.
    D = squareform(pdist(jittered_grid))
    Y = CCA(2, **PRE, init="random", n_epochs=1, alpha0=1e-9, random_state=3).fit_transform(D)
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
    a = CCA(2, **PRE, init="random", n_epochs=3, random_state=5).fit_transform(D)
    b = CCA(2, **PRE, init="random", n_epochs=3, random_state=5).fit_transform(D)
    c = CCA(2, **PRE, init="random", n_epochs=3, random_state=6).fit_transform(D)
    g = CCA(2, **PRE, init="random", n_epochs=3,
            random_state=np.random.default_rng(5)).fit_transform(D)
    r1 = CCA(2, **PRE, init="random", n_epochs=3,
             random_state=np.random.RandomState(5)).fit_transform(D)
    r2 = CCA(2, **PRE, init="random", n_epochs=3,
             random_state=np.random.RandomState(5)).fit_transform(D)
    assert np.array_equal(a, b)
    assert np.array_equal(a, g)
    assert not np.allclose(a, c)
    assert np.array_equal(r1, r2) and not np.allclose(r1, a)


def test_euclidean_metric_equals_precomputed(curled_sheet):
    X = curled_sheet[0][:120]
    a = CCA(3, metric="euclidean", n_epochs=3, random_state=2).fit_transform(X)
    b = CCA(3, **PRE, n_epochs=3, random_state=2).fit_transform(squareform(pdist(X)))
    assert np.array_equal(a, b)


def test_fitted_attributes_and_warm_start(jittered_grid):
    D = squareform(pdist(jittered_grid[:60]))
    est = CCA(2, **PRE, n_epochs=4, random_state=0).fit(D)
    assert est.embedding_.shape == (60, 2)
    assert est.n_iter_ == 4
    assert est.n_features_in_ == 60
    assert est.stress_ >= 0
    assert est.lambda0_ == pytest.approx(3 * np.std(classical_mds(D, 2), axis=0).max())
    # A warm start at the answer stays there: every dx == dy, the rule is a no-op.
    Y = CCA(2, **PRE, n_epochs=2, random_state=0).fit_transform(D, init=jittered_grid[:60])
    np.testing.assert_allclose(Y, jittered_grid[:60], atol=1e-12)
    assert clone(est).get_params()["n_epochs"] == 4


def test_stress_drops_from_a_bad_start(jittered_grid):
    D = squareform(pdist(jittered_grid[:80]))
    start = CCA(2, **PRE, init="random", n_epochs=1, alpha0=1e-9,
                random_state=1).fit_transform(D)
    end = CCA(2, **PRE, init="random", n_epochs=10, random_state=1).fit_transform(D)
    # Compared at one radius covering the whole grid (stress_ uses the final, tiny one).
    assert cca_stress(D, end, 1.0) < 1e-2 * cca_stress(D, start, 1.0)


BAD_DISTANCES = [
    (np.zeros((3, 4)), "square"),
    (np.array([[0.0, 1.0], [2.0, 0.0]]), "not symmetric"),
    (np.array([[0.0, np.nan], [np.nan, 0.0]]), "NaN"),
    (np.array([[0.0, np.inf], [np.inf, 0.0]]), "infinity"),
    (np.array([[0.0, -1.0], [-1.0, 0.0]]), "Negative values"),
    (np.zeros((1, 1)), "1 sample"),
    (np.zeros(4), "2D array"),
    (np.array([[0.0, 1j], [1j, 0.0]]), "Complex data not supported"),
    (sparse.csr_array(np.array([[0.0, 1.0], [1.0, 0.0]])), "[Ss]parse"),
]


@pytest.mark.parametrize("X, word", BAD_DISTANCES)
def test_bad_distance_matrices_raise(X, word):
    with pytest.raises((ValueError, TypeError), match=word):
        CCA(**PRE).fit(X)


@pytest.mark.parametrize("X, word", BAD_DISTANCES)
def test_check_distance_matrix_names_the_argument(X, word):
    with pytest.raises((ValueError, TypeError), match=word) as raised:
        check_distance_matrix(X, "distance")
    if word != "[Ss]parse":          # scipy's sparse refusal names no argument
        assert "distance" in str(raised.value)


@pytest.mark.parametrize("X, word", [
    (np.array([[0.0, np.nan], [1.0, 2.0], [3.0, 4.0]]), "NaN"),
    (np.zeros((1, 3)), "1 sample"),
    (np.zeros((4, 0)), "0 feature"),
    (sparse.csr_array(np.eye(3)), "[Ss]parse"),
])
def test_bad_feature_data_raise(X, word):
    with pytest.raises((ValueError, TypeError), match=word):
        CCA().fit(X)


def test_a_distance_matrix_read_as_points_warns(jittered_grid):
    D = squareform(pdist(jittered_grid[:30]))
    with pytest.warns(UserWarning, match="precomputed"):
        CCA(n_epochs=1, random_state=0).fit(D)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        CCA(**PRE, n_epochs=1, random_state=0).fit(D)
        CCA(n_epochs=1, random_state=0).fit(np.random.default_rng(0).random((30, 30)))


def test_fit_and_fit_transform_agree_and_leave_init_alone(curled_sheet):
    X = curled_sheet[0][:50]
    start = np.linspace(0.0, 1.0, 50)[:, None]
    kept = start.copy()
    est = CCA(1, n_epochs=3, random_state=7)
    Y = est.fit_transform(X, init=start)
    assert np.array_equal(CCA(1, n_epochs=3, random_state=7).fit(X, init=start).embedding_, Y)
    assert np.array_equal(est.embedding_, Y)
    assert np.array_equal(start, kept)         # the steps moved a copy
    assert not np.allclose(Y, start)
    # the constructor's init is the same start
    assert np.array_equal(CCA(1, init=start, n_epochs=3, random_state=7).fit_transform(X), Y)
    assert est.n_features_in_ == 3


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
        CCA(**{"metric": "precomputed", **params}).fit(D)


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
        CCA(**PRE, kernel="numba").fit(D)
    assert CCA(**PRE, kernel="auto", n_epochs=2, random_state=0).fit_transform(D).shape == (5, 2)


def test_docstring_example_runs():
    failed, attempted = doctest.testmod(cca_module, optionflags=doctest.ELLIPSIS)
    assert attempted > 0 and failed == 0


def _check_id(value):
    if isinstance(value, CCA):
        return value.metric
    keywords = "".join(f"({k}={v})" for k, v in getattr(value, "keywords", {}).items())
    return getattr(value, "func", value).__name__ + keywords


# scikit-learn's estimator checks (all of them, none expected to fail), on
# feature data and on distance matrices.
ESTIMATOR_CHECKS = [pair for estimator in (CCA(n_epochs=2), CCA(metric="precomputed", n_epochs=2))
                    for pair in estimator_checks_generator(estimator)]


@pytest.mark.parametrize("estimator, check", ESTIMATOR_CHECKS, ids=_check_id)
def test_sklearn_estimator_checks(estimator, check):
    check(estimator)
