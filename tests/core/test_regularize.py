"""Metric regularisation from equality sets (paper Eqs. common_distance,
distance_equalities, iterative unfolding)."""
import numpy as np
import pytest
from scipy.spatial.distance import pdist, squareform

from sensorispace_ros.core.cca import CCA
from sensorispace_ros.core.quality import affine_residual
from sensorispace_ros.core.regularize import iterate_regularization, regularize_metric, set_spread


def lattice_with_warped_metric(n=10):
    """A lattice whose metric is that of a smooth nonlinear warp of it, and
    equality sets = all ordered pairs with the same lattice displacement."""
    lattice = np.stack(np.meshgrid(np.arange(n), np.arange(n)), -1).reshape(-1, 2).astype(float)
    x, y = lattice[:, 0] / (n - 1), lattice[:, 1] / (n - 1)
    warped = np.stack([x + 0.35 * np.sin(np.pi * y), y + 0.25 * x ** 2, 0.4 * np.cos(2 * x)], -1)
    i, j = np.nonzero(~np.eye(n * n, dtype=bool))
    _, set_ids = np.unique(lattice[j] - lattice[i], axis=0, return_inverse=True)
    return lattice, squareform(pdist(warped)), np.stack([i, j], -1), set_ids.ravel()


def test_one_step_equalises_each_set_and_keeps_the_rest():
    rng = np.random.default_rng(0)
    D = squareform(pdist(rng.random((8, 3))))
    pairs = np.array([[0, 1], [2, 3], [4, 5], [1, 6], [7, 2]])
    set_ids = np.array([10, 10, 10, 4, 4])
    R = regularize_metric(D, pairs, set_ids)
    first = np.mean([D[0, 1], D[2, 3], D[4, 5]])
    second = np.mean([D[1, 6], D[7, 2]])
    for (i, j), target in zip(pairs, [first] * 3 + [second] * 2):
        assert R[i, j] == pytest.approx(target, abs=1e-15)
        assert R[j, i] == pytest.approx(target, abs=1e-15)
    constrained = np.zeros_like(D, dtype=bool)
    constrained[pairs[:, 0], pairs[:, 1]] = constrained[pairs[:, 1], pairs[:, 0]] = True
    assert np.array_equal(R[~constrained], D[~constrained])
    assert np.array_equal(R, R.T)
    assert set_spread(R, pairs, set_ids) == pytest.approx(0.0, abs=1e-15)
    assert set_spread(D, pairs, set_ids) > 0.05


def test_pair_in_two_sets_takes_the_mean_of_their_means():
    D = squareform(pdist(np.array([[0.0], [1.0], [3.0], [6.0]])))
    # (0,1) is in set 0 with (2,3) and, reversed, in set 1 with (1,2).
    R = regularize_metric(D, np.array([[0, 1], [2, 3], [1, 0], [1, 2]]), np.array([0, 0, 1, 1]))
    assert R[0, 1] == pytest.approx(((1 + 3) / 2 + (1 + 2) / 2) / 2)
    assert R[2, 3] == pytest.approx(2.0)
    assert R[1, 2] == pytest.approx(1.5)


def test_iterations_lower_the_spread_and_make_the_embedding_affine():
    lattice, D0, pairs, set_ids = lattice_with_warped_metric()
    seen = []
    result = iterate_regularization(D0, pairs, set_ids, n_components=2, n_iterations=4,
                                    cca_params={"n_epochs": 10}, random_state=0,
                                    callback=lambda it, Y: seen.append((it, Y.shape)))
    assert seen == [(k, (100, 2)) for k in (1, 2, 3, 4)]
    assert result.set_spread[0] > 0.05
    assert result.set_spread[-1] < 1e-3 * result.set_spread[0]
    assert np.all(np.diff(result.set_spread) < 0)
    assert len(result.embeddings) == len(result.timings_s) == 4
    np.testing.assert_allclose(result.distances, squareform(pdist(result.embeddings[-1])))
    initial = CCA(2, metric="precomputed", n_epochs=10, random_state=0).fit_transform(D0)
    assert affine_residual(initial, lattice) > 0.1
    assert affine_residual(result.embeddings[-1], lattice) < 1e-3


def test_seeded_iterations_repeat():
    lattice, D0, pairs, set_ids = lattice_with_warped_metric(6)
    kwargs = dict(n_components=2, n_iterations=2, cca_params={"n_epochs": 3})
    a = iterate_regularization(D0, pairs, set_ids, random_state=3, **kwargs)
    b = iterate_regularization(D0, pairs, set_ids, random_state=3, **kwargs)
    assert np.array_equal(a.embeddings[-1], b.embeddings[-1])


def test_warm_start_init_is_used():
    lattice, D0, pairs, set_ids = lattice_with_warped_metric(6)
    # Starting at the answer with a tiny step keeps the answer.
    result = iterate_regularization(
        squareform(pdist(lattice)), pairs, set_ids, n_components=2, n_iterations=1,
        cca_params={"n_epochs": 1, "alpha0": 1e-12}, init=lattice)
    np.testing.assert_allclose(result.embeddings[0], lattice, atol=1e-9)


@pytest.mark.parametrize("pairs, set_ids, word", [
    (np.array([[0, 1, 2]]), np.array([0]), "pairs must have shape"),
    (np.array([[0, 1]]), np.array([0, 1]), "set_ids must have shape"),
    (np.array([[0, 9]]), np.array([0]), "outside"),
    (np.array([[2, 2]]), np.array([0]), "itself"),
    (np.array([[0.0, 1.0]]), np.array([0]), "integer"),
])
def test_bad_sets_raise(pairs, set_ids, word):
    D = squareform(pdist(np.arange(4.0)[:, None]))
    with pytest.raises(ValueError, match=word):
        regularize_metric(D, pairs, set_ids)


def test_bad_iteration_arguments_raise():
    D = squareform(pdist(np.arange(4.0)[:, None]))
    pairs, ids = np.array([[0, 1]]), np.array([0])
    with pytest.raises(ValueError, match="n_iterations"):
        iterate_regularization(D, pairs, ids, n_components=1, n_iterations=0)
    with pytest.raises(ValueError, match="cca_params"):
        iterate_regularization(D, pairs, ids, n_components=1, cca_params={"init": "random"})
