"""The known POVs nearest a motor state (``PovStore.nearest``): a tree over
the first POVs and the later ones one by one give exactly what measuring
every sample on the torus of phases gives."""
import numpy as np
import pytest

from sensorispace_ros.core.naive.points_of_view import PovStore


def _brute(samples, state, allowed, k):
    gap = (samples - state + np.pi) % (2.0 * np.pi) - np.pi
    reach = np.linalg.norm(gap, axis=2).min(axis=1)
    ids = np.flatnonzero(allowed)
    return ids[np.argsort(reach[ids], kind="stable")[:k]]


def _store(rng, count, n_samples=20, motors=3):
    store = PovStore(n_samples, motors)
    centres = rng.uniform(-4.0, 10.0, size=(count, motors))       # phases beyond one turn too
    for centre in centres:
        store.append(centre + 0.3 * rng.normal(size=(n_samples, motors)))
    return store


@pytest.mark.parametrize("share", [1.0, 0.5, 0.05])
def test_the_nearest_povs_are_those_of_every_sample(share):
    rng = np.random.default_rng(7)
    store = _store(rng, 60)
    store.nearest(np.zeros(3), np.ones(60, dtype=bool), 3)       # the tree over these 60
    for _ in range(3):                                   # POVs appended after the tree
        store.append(rng.uniform(0.0, 6.0, size=(20, 3)))
    assert store._near_built == 60
    for _ in range(40):
        state = rng.uniform(-7.0, 13.0, size=3)
        allowed = rng.uniform(size=store.count) < share
        allowed[rng.integers(store.count)] = True
        np.testing.assert_array_equal(store.nearest(state, allowed, 3),
                                      _brute(store.samples, state, allowed, 3))


def test_an_undo_leaves_the_nearest_povs_of_the_store_it_brings_back():
    rng = np.random.default_rng(8)
    store = _store(rng, 40)
    mark = store.mark()
    before = store.samples.copy()
    for _ in range(20):                                   # past an eighth: the tree is rebuilt
        store.append(rng.normal(size=(20, 3)))
    store.nearest(np.zeros(3), np.ones(store.count, dtype=bool), 3)
    store.truncate(mark)
    for _ in range(20):
        state = rng.uniform(-7.0, 13.0, size=3)
        allowed = np.ones(store.count, dtype=bool)
        np.testing.assert_array_equal(store.nearest(state, allowed, 3),
                                      _brute(before, state, allowed, 3))
