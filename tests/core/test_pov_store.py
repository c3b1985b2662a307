"""PovStore: the POVs' samples, their separation and the POVs near a motor
state, on the torus of phases; pickled (checkpoints) without its tree."""
import copy
import pickle

import numpy as np
import pytest

from sensorispace_ros.core.naive.neighbours import curve_distances
from sensorispace_ros.core.naive.points_of_view import PERIOD, PovStore


def _loops(count, n_samples=24, spacing=0.3):
    """``count`` loops along joint 1, joint 0 at ``spacing * k`` (odd ones
    one period further), each at one joint-2 phase."""
    angle = np.linspace(0.0, PERIOD, n_samples, endpoint=False)
    return [np.stack([np.full(n_samples, spacing * k + PERIOD * (k % 2)), angle,
                      np.full(n_samples, 0.1 * k)], axis=1) for k in range(count)]


def _store(loops):
    store = PovStore(len(loops[0]), loops[0].shape[1])
    for loop in loops:
        store.append(loop)
    return store


def test_a_sample_whose_phase_rounds_up_to_the_period_is_at_zero():
    # A phase just below 0 is 2 pi after np.mod: the store places it at 0,
    # next to a sample at 0.2 of the other POV.
    below_zero = -1e-17
    assert np.mod(below_zero, PERIOD) == PERIOD
    first = np.zeros((8, 3))
    first[:, 1] = np.linspace(1.0, 4.0, 8)
    first[0] = [below_zero, 3.0, 3.0]
    second = first + [0.0, 0.0, 0.2]
    second[0] = [0.0, 3.0, 3.2]
    store = _store([first, second])
    assert store.separation() == pytest.approx(0.2)
    assert store.near(np.array([PERIOD, 3.0, 3.1]), 0.15).tolist() == [0, 1]
    assert store.near(np.array([below_zero, 3.0, 2.9]), 0.15).tolist() == [0]


def test_near_finds_the_povs_with_a_sample_within_the_radius():
    loops = _loops(20)
    store = _store(loops[:16])
    rng = np.random.default_rng(0)
    points = rng.uniform(-PERIOD, 2 * PERIOD, size=(40, 3))
    store.near(points[0], 0.5)                  # the tree holds 16 POVs
    for loop in loops[16:]:                     # measured one by one
        store.append(loop)
    for point in points:
        expected = np.flatnonzero(curve_distances(point, store.samples) <= 0.5)
        assert sorted(store.near(point, 0.5).tolist()) == expected.tolist()


@pytest.mark.parametrize("round_trip", [lambda s: pickle.loads(pickle.dumps(s)), copy.deepcopy])
def test_a_pickled_store_leaves_its_tree_and_answers_the_same(round_trip):
    loops = _loops(20)
    store = _store(loops[:16])
    rng = np.random.default_rng(1)
    points = rng.uniform(0.0, PERIOD, size=(30, 3))
    store.near(points[0], 0.6)
    for loop in loops[16:]:
        store.append(loop)
    assert b"cKDTree" not in pickle.dumps(store)
    restored = round_trip(store)
    assert restored._near_tree is None and restored._near_built == 16
    for point in points:
        assert restored.near(point, 0.6).tolist() == store.near(point, 0.6).tolist()
    assert restored.separation() == store.separation()
    # Grown by an eighth, both rebuild over all their POVs.
    more = _loops(24)[20:]
    for loop in more:
        store.append(loop)
        restored.append(loop)
    for point in points:
        assert restored.near(point, 0.6).tolist() == store.near(point, 0.6).tolist()
    assert restored._near_built == store._near_built == 24


def test_truncate_brings_the_store_back_to_its_mark():
    rng = np.random.default_rng(5)
    store = PovStore(10, 3)
    for _ in range(40):
        store.append(rng.normal(size=(10, 3)))
    before = store.samples.copy()
    point = before[3, 0]
    near_before = store.near(point, 0.5)
    mark = store.mark()
    for _ in range(30):                       # grows past the tree and its buffer
        store.append(rng.normal(size=(10, 3)))
    store.near(point, 0.5)
    store.truncate(mark)
    np.testing.assert_array_equal(store.samples, before)
    np.testing.assert_array_equal(store.near(point, 0.5), near_before)
    assert store.append(rng.normal(size=(10, 3))) == 40


def test_a_pickled_store_holds_its_povs_only_and_grows_again():
    store = PovStore(10, 3)
    for k in range(17):
        store.append(np.full((10, 3), float(k)))
    copied = pickle.loads(pickle.dumps(store))
    assert len(copied._data) == 17
    np.testing.assert_array_equal(copied.samples, store.samples)
    assert copied.append(np.zeros((10, 3))) == 17 and copied.count == 18
    empty = pickle.loads(pickle.dumps(PovStore(10, 3)))
    assert empty.append(np.ones((10, 3))) == 0
