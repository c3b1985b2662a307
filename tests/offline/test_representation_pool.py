"""build_representation with a pool an rclpy process may create:
the chains' numbers are those of the sequential path, and no worker outlives
stop_chain_pool."""
from __future__ import annotations

import os
import time
from concurrent.futures import Executor

import numpy as np
import pytest

from sensorispace_ros.offline import chain_pool
from sensorispace_ros.offline.representation import DIMENSIONS, build_representation
from sensorispace_ros.config import load_config


def small_input():
    """12 points of view (loops of 20 samples around scattered motor states)
    and equality rows that join them in 4 sets."""
    rng = np.random.default_rng(3)
    centres = rng.uniform(-2.0, 2.0, size=(12, 1, 4))
    phase = np.linspace(0.0, 2 * np.pi, 20, endpoint=False)[None, :, None]
    povs = centres + 0.05 * np.cos(phase + np.arange(4)[None, None, :])
    pairs = np.array([[0, 1], [2, 3], [4, 5], [6, 7], [8, 9], [10, 11], [1, 2], [5, 6]])
    set_ids = np.array([0, 0, 1, 1, 2, 2, 3, 3])
    cfg = load_config(None, overrides={"representation.cca.n_epochs": 5,
                                       "representation.regularization.iterations": 2})
    return povs, pairs, set_ids, cfg


def gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


@pytest.mark.parametrize("start_method", chain_pool.CHAIN_START_METHODS)
def test_chains_in_a_chain_pool_equal_the_sequential_path_bitwise(start_method):
    povs, pairs, set_ids, cfg = small_input()
    sequential = build_representation(povs, pairs, set_ids, cfg, 7, processes=1)
    pool = chain_pool.start_chain_pool(start_method)
    try:
        pids = chain_pool.chain_pool_pids(pool)
        submitted = []

        class Recording(Executor):
            def submit(self, fn, /, *args, **kwargs):
                submitted.append(args[5])                    # the chain's name
                return pool.submit(fn, *args, **kwargs)

        pooled = build_representation(povs, pairs, set_ids, cfg, 7, executor=Recording())
        assert sorted(submitted) == sorted(DIMENSIONS)
        assert chain_pool.chain_pool_pids(pool) == pids      # the warmed workers ran them
    finally:
        chain_pool.stop_chain_pool(pool)
    assert len(pids) == len(DIMENSIONS) and os.getpid() not in pids
    for dim in DIMENSIONS:
        assert pooled.before[dim].tobytes() == sequential.before[dim].tobytes()
        assert pooled.iterations[dim].tobytes() == sequential.iterations[dim].tobytes()
        assert pooled.set_spread[dim].tobytes() == sequential.set_spread[dim].tobytes()
        assert pooled.iterations[dim].shape == (2, len(povs), DIMENSIONS[dim])
    assert all(gone(pid) for pid in pids)
    # a different seed changes the numbers, so the equality above is not vacuous
    other = build_representation(povs, pairs, set_ids, cfg, 8, processes=1)
    assert not np.array_equal(other.before["2d"], sequential.before["2d"])


def test_stop_chain_pool_ends_a_worker_in_the_middle_of_a_task():
    pool = chain_pool.start_chain_pool("forkserver")
    pids = chain_pool.chain_pool_pids(pool)
    busy = pool.submit(time.sleep, 60)
    time.sleep(0.2)
    started = time.monotonic()
    chain_pool.stop_chain_pool(pool, grace_s=0.2)
    assert time.monotonic() - started < 5.0
    assert all(gone(pid) for pid in pids)
    with pytest.raises(Exception):
        busy.result(timeout=5)


def test_processes_and_executor_together_are_rejected():
    povs, pairs, set_ids, cfg = small_input()
    with pytest.raises(ValueError, match="executor"):
        build_representation(povs, pairs, set_ids, cfg, 0, processes=1, executor=object())
    with pytest.raises(ValueError, match="start_method"):
        chain_pool.start_chain_pool("fork")


def test_the_chain_pool_has_one_worker_per_embedding_chain():
    assert chain_pool.CHAIN_WORKERS == len(DIMENSIONS)
