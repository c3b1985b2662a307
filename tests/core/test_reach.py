"""Reaching through a representation: pruned graph, Dijkstra, motor path."""
import numpy as np
import pytest
from scipy.spatial.distance import pdist, squareform

from sensorispace_ros.core.hausdorff import motor_distance
from sensorispace_ros.core.reach import (automatic_radius, motor_trajectory, path_straightness,
    pruned_graph, reaching_evaluation, shortest_path)


@pytest.fixture(scope="module")
def lattice():
    n = 20
    return np.stack(np.meshgrid(np.arange(n), np.arange(n)), -1).reshape(-1, 2).astype(float)


def test_lattice_metric_gives_straight_paths(lattice):
    result = reaching_evaluation(squareform(pdist(lattice)), lattice, n_pairs=60, random_state=0)
    assert result["straightness_median"] < 1.05
    assert result["unreachable"] == 0 and result["n_components"] == 1
    assert len(result["pairs"]) == len(result["straightness"]) == 60
    assert all(s != t for s, t in result["pairs"])


def test_distorted_metric_bends_paths(lattice):
    x, y = (lattice / lattice.max()).T
    # Internal distances along x grow with y: shortest internal paths dip to low y.
    warped = np.stack([x * (1 + 12 * y ** 2), y], -1)
    straight = reaching_evaluation(squareform(pdist(lattice)), lattice, n_pairs=60, random_state=0)
    bent = reaching_evaluation(squareform(pdist(warped)), lattice, n_pairs=60, random_state=0)
    assert bent["straightness_median"] > 1.1
    assert bent["straightness_median"] > straight["straightness_median"] + 0.05


def test_automatic_radius_respects_max_degree_and_is_the_largest(lattice):
    D = squareform(pdist(lattice + np.random.default_rng(0).normal(0, 0.05, lattice.shape)))
    for max_degree in (4, 12, 50):
        graph = pruned_graph(D, max_degree=max_degree)
        degree = np.diff(graph.indptr)
        assert degree.max() <= max_degree
        wider = pruned_graph(D, radius=np.nextafter(graph.radius, np.inf))
        assert np.diff(wider.indptr).max() > max_degree
        assert graph.radius == automatic_radius(D, max_degree)


def test_graph_is_symmetric_with_distance_weights(lattice):
    D = squareform(pdist(lattice[:50]))
    graph = pruned_graph(D, radius=2.5)
    dense = graph.toarray()
    assert np.array_equal(dense, dense.T)
    inside = (D < 2.5) & ~np.eye(50, dtype=bool)
    assert np.array_equal(dense != 0, inside)
    assert np.array_equal(dense[inside], D[inside])


def test_shortest_path_on_a_line_takes_every_step():
    line = np.arange(6.0)[:, None]
    graph = pruned_graph(squareform(pdist(line)), radius=1.5)
    assert shortest_path(graph, 0, 5) == [0, 1, 2, 3, 4, 5]
    assert shortest_path(graph, 4, 1) == [4, 3, 2, 1]


def test_disconnected_graph_is_reported_not_hidden():
    points = np.vstack([np.arange(4.0)[:, None], 100 + np.arange(4.0)[:, None]])
    D = squareform(pdist(points))
    graph = pruned_graph(D, radius=1.5)
    assert graph.n_components == 2
    with pytest.raises(ValueError, match="not reachable"):
        shortest_path(graph, 0, 6)
    result = reaching_evaluation(D, np.hstack([points, 0 * points]), n_pairs=40,
                                 radius=1.5, random_state=1)
    assert result["unreachable"] > 0
    assert result["straightness"].count(None) == result["unreachable"]


def test_motor_trajectory_picks_the_nearest_sample():
    rng = np.random.default_rng(4)
    povs = rng.uniform(-2 * np.pi, 2 * np.pi, size=(6, 30, 4))
    path = [3, 0, 5, 1]
    states = motor_trajectory(povs, path, start_sample=7)
    expected = [povs[3, 7]]
    for node in path[1:]:
        best = min(range(30), key=lambda s: motor_distance(povs[node, s], expected[-1]))
        expected.append(povs[node, best])
    assert np.array_equal(states, np.array(expected))


def test_path_straightness_of_known_paths():
    positions = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [2.0, 2.0]])
    assert path_straightness([0, 1, 2], positions) == pytest.approx(np.sqrt(2))
    assert path_straightness([0, 2, 3], positions) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="same position"):
        path_straightness([1, 2, 1], positions)


def test_evaluation_is_seeded(lattice):
    D = squareform(pdist(lattice))
    a = reaching_evaluation(D, lattice, n_pairs=10, random_state=5)
    b = reaching_evaluation(D, lattice, n_pairs=10, random_state=5)
    c = reaching_evaluation(D, lattice, n_pairs=10, random_state=6)
    assert a == b
    assert a["pairs"] != c["pairs"]


@pytest.mark.parametrize("kwargs, word", [
    ({"max_degree": 0}, "max_degree"),
    ({"radius": -1.0}, "radius"),
    ({"n_pairs": 0}, "n_pairs"),
])
def test_bad_parameters_raise(lattice, kwargs, word):
    with pytest.raises(ValueError, match=word):
        reaching_evaluation(squareform(pdist(lattice[:20])), lattice[:20], **kwargs)
