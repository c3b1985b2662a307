"""Worker processes for the representation's 2-D and 3-D chains.

A process with one Python thread and without rclpy forks its workers
(``can_fork``). A process that must not fork (a ROS node: DDS threads hold
locks) starts a pool whose workers come from a forkserver or spawn
(``start_chain_pool``), warmed up once, and stops it by its workers' PIDs
(``stop_chain_pool``).
"""
from __future__ import annotations

import os
import time
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from concurrent.futures import ProcessPoolExecutor

# What a chain worker imports, loaded once by the forkserver so that every
# worker forked from it starts with them.
CHAIN_WORKER_MODULES = ("numpy", "scipy.linalg", "scipy.spatial.distance", "sklearn.base",
                        "sensorispace_ros.core.cca", "sensorispace_ros.core.regularize",
                        "sensorispace_ros.offline.representation")
CHAIN_START_METHODS = ("forkserver", "spawn")
# One worker per embedding chain (offline.representation.DIMENSIONS: 2-D and 3-D).
CHAIN_WORKERS = 2


def can_fork() -> bool:
    """Whether worker processes may be forked from this one.

    fork by default, because spawn and forkserver re-import the caller's
    main script (a script without a ``__main__`` guard would fail). A forked
    child inherits every lock held by another thread at that moment, so only
    a process with one Python thread and without rclpy (DDS threads) forks;
    the ROS representation node passes a ``start_chain_pool`` pool instead.
    """
    import sys
    import threading

    return (hasattr(os, "fork") and threading.active_count() == 1
            and "rclpy" not in sys.modules)


def start_chain_pool(start_method: str = "forkserver") -> ProcessPoolExecutor:
    """A pool for ``build_representation(executor=...)`` that a process with
    other threads (rclpy) may create: its workers come from a forkserver
    (or spawn), never from a fork of the caller.

    Both workers are started and warmed up here (imports, numba's cached CCA
    kernel loaded), so a caller that starts the pool early pays nothing of it
    when the chains run. Stop it with ``stop_chain_pool``. As with any
    forkserver or spawn pool, each worker imports the caller's main module
    again: a script needs an ``if __name__ == "__main__":`` guard (the node
    modules and console scripts have one), else the warm-up fails here.
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    if start_method not in CHAIN_START_METHODS:
        raise ValueError(f"start_method must be one of {', '.join(CHAIN_START_METHODS)}, "
                         f"got {start_method!r}")
    context = multiprocessing.get_context(start_method)
    if start_method == "forkserver":
        # Only read when this process starts its forkserver; without it the
        # forkserver would import the caller's __main__ (here: rclpy).
        context.set_forkserver_preload(list(CHAIN_WORKER_MODULES))
    pool = ProcessPoolExecutor(max_workers=CHAIN_WORKERS, mp_context=context,
                               initializer=_chain_worker_started)
    try:
        # Submitted together, the warm-ups find no idle worker: one worker each.
        for future in [pool.submit(_warm_chain_worker) for _ in range(CHAIN_WORKERS)]:
            future.result()
    except BaseException:
        stop_chain_pool(pool)
        raise
    return pool


def chain_pool_pids(pool: ProcessPoolExecutor) -> list[int]:
    """PIDs of the pool's worker processes (for checks that none is left)."""
    return sorted(getattr(pool, "_processes", None) or {})


def stop_chain_pool(pool: ProcessPoolExecutor, grace_s: float = 1.0) -> None:
    """Shut ``pool`` down and wait until its workers have exited.

    Idle workers leave at once; a chain still running (the caller is being
    stopped mid-build) is terminated after ``grace_s``, so no worker outlives
    its caller's clean shutdown.
    """
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + grace_s
    for process in processes:
        process.join(max(0.0, deadline - time.monotonic()))
    for process in processes:
        if process.exitcode is None:
            process.terminate()
            process.join(1.0)
        if process.exitcode is None:
            process.kill()
            process.join()


def _chain_worker_started() -> None:
    """Initializer of a chain worker: Ctrl-C is its parent's to handle (the
    parent stops the pool), and it exits when its parent dies, even by
    SIGKILL (a worker waiting for tasks would otherwise wait forever)."""
    import multiprocessing
    import signal
    import threading

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent = multiprocessing.parent_process()
    if parent is not None:
        threading.Thread(target=_exit_with, args=(parent,), name="parent-watch",
                         daemon=True).start()


def _exit_with(parent) -> None:
    parent.join()
    os._exit(1)


def _warm_chain_worker() -> int:
    """A tiny CCA, so that the worker has loaded what a chain uses."""
    import numpy as np
    from scipy.spatial.distance import pdist, squareform

    from sensorispace_ros.core.cca import CCA

    points = np.arange(16, dtype=float).reshape(8, 2) ** 1.5
    CCA(n_components=2, metric="precomputed", init="mds", n_epochs=1,
        random_state=0).fit_transform(squareform(pdist(points)))
    return os.getpid()
