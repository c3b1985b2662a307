"""From a strategy's output to the paper's numbers and figures.

Three steps, each callable on its own so the offline command, the ROS
representation node and ``sensorispace analyze BAG`` share them:

``run_strategy(cfg, strategy, seed)``
    simulation 1 and 2 with the ``paper`` (analytic) or ``naive`` strategy:
    points of view, equality sets, counters, and ground truth kept apart.
``build_representation(povs, pairs, set_ids, cfg, seed)``
    what the agent builds from its own data only: Hausdorff metric, CCA
    projections (2-D, 3-D), metric regularisation. No ground truth.
``evaluate(representation, true_positions, povs, cfg, seed)``
    numbers that compare the representation with the ground truth.

``reproduce`` chains them and writes ``metrics.json``, ``arrays.npz`` and
``figures/*.png``.
"""
from __future__ import annotations

import json
import math
import os
import time
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterator

import numpy as np
from scipy.spatial.distance import pdist, squareform
from scipy.stats import spearmanr

from sensorispace_ros import config as config_mod
from sensorispace_ros.core.seeding import rng_for

if TYPE_CHECKING:
    from concurrent.futures import Executor, ProcessPoolExecutor

STRATEGIES = ("paper", "naive")
DIMENSIONS = {"2d": 2, "3d": 3}
STAGES = ("before", "after")
METRICS_FILE = "metrics.json"
ARRAYS_FILE = "arrays.npz"
FIGURES_DIR = "figures"
# Significant digits written to metrics.json: far below every acceptance bar,
# and it keeps last-bit noise of BLAS reductions out of run-to-run diffs.
FLOAT_DIGITS = 12


# ---------------------------------------------------------------------------
# Data passed between the steps


@dataclass
class StrategyOutput:
    """What a strategy produced.

    ``povs``, ``pairs`` and ``set_ids`` are the agent's own data;
    ``true_positions`` (sensor position of each POV) and ``arrays`` are ground
    truth and figure material, for evaluation only.
    """

    povs: np.ndarray                 # (P, N, 4) motor states of each point of view
    pairs: np.ndarray                # (K, 2) POV index pairs (i -> j) of equality sets
    set_ids: np.ndarray              # (K,) equality set of each pair
    true_positions: np.ndarray       # (P, 2) ground truth sensor positions
    metrics: dict                    # dotted keys: exploration.*, pov.*, naive.*, ...
    arrays: dict                     # figure / re-evaluation material
    timings_s: dict


@dataclass
class Representation:
    """The agent's internal representation of its points of view."""

    distance: np.ndarray                         # (P, P) Hausdorff metric
    before: dict                                 # "2d" -> (P, 2), "3d" -> (P, 3)
    iterations: dict                             # "2d" -> (I, P, 2), one per iteration
    set_spread: dict                             # "2d" -> (I,) per iteration
    timings_s: dict = field(default_factory=dict)

    @property
    def after(self) -> dict:
        return {dim: emb[-1] for dim, emb in self.iterations.items()}

    def embedding(self, dim: str, stage: str) -> np.ndarray:
        return self.before[dim] if stage == "before" else self.iterations[dim][-1]


# ---------------------------------------------------------------------------
# Stage timing / progress


@contextmanager
def _stage(progress, name: str, timings: dict, total: float | None = None) -> Iterator[Callable]:
    """Time ``name`` into ``timings`` and show it on ``progress`` if given."""
    display = progress.stage(name, total) if hasattr(progress, "stage") else nullcontext()
    start = time.perf_counter()
    with display:
        yield progress
    timings[name] = timings.get(name, 0.0) + time.perf_counter() - start


def _random_state(seed: int, stream: str) -> int:
    """An integer seed for scikit-learn style ``random_state`` arguments."""
    return int(rng_for(seed, stream).integers(2 ** 31 - 1))


# ---------------------------------------------------------------------------
# Strategies


def world_params(cfg: dict) -> dict:
    """``core.exploration.build_world`` parameters from the configuration."""
    world, lights, retina = cfg["world"], cfg["world"]["lights"], cfg["world"]["retina"]
    return {
        "m0": tuple(cfg["arm"]["initial_motor_state"]),
        "grid_half_width": world["grid_half_width"],
        "grid_count": world["grid_count"],
        "n_lights": lights["count"],
        "light_radius_min": lights["radius_min"],
        "light_radius_max": lights["radius_max"],
        "n_receptors": retina["receptors"],
        "retina_half_width": retina["half_width"],
        "min_lights_in_view": lights["min_in_view"],
        "redistribution_probability": world["redistribution_probability"],
        "order": world["schedule"],
    }


def pov_params(cfg: dict) -> dict:
    pov = cfg["pov"]
    return {"step": pov["step"], "n_samples": pov["n_samples"],
            "min_steps": pov["min_steps"], "close_tol": pov["close_tol"]}


def run_strategy(cfg: dict, strategy: str, seed: int, progress=None) -> StrategyOutput:
    if strategy == "paper":
        return run_paper(cfg, seed, progress)
    if strategy == "naive":
        return run_naive_strategy(cfg, seed, progress)
    raise ValueError(f"strategy must be one of {', '.join(STRATEGIES)}, got {strategy!r}")


def run_paper(cfg: dict, seed: int, progress=None) -> StrategyOutput:
    """Simulations 1 and 2 with the paper's analytic shortcuts."""
    from sensorispace_ros.core.paper.equality_sets import equality_sets_from_poses
    from sensorispace_ros.core.paper.exploration import build_world, explore_paper

    timings: dict = {}
    with _stage(progress, "exploration", timings):
        world = build_world(seed, world_params(cfg))
        explored = explore_paper(
            m0=world.m0, grid=world.grid, events=world.events,
            initial_center=world.initial_center, threshold=cfg["compensation"]["threshold"],
            compensation_options={"initial_simplex_size": cfg["compensation"]["initial_simplex"]},
            progress=progress)
    with _stage(progress, "points_of_view", timings):
        sampled = _sample_points_of_view(explored.motor_states, cfg, progress)
    valid = np.asarray(sampled.valid, dtype=bool)
    povs = sampled.samples[valid]
    true_poses = explored.true_poses[valid]
    # Simulation 2 (paper Sec. 5.1, "optimized simulation setting"): the
    # compensating POV of a displacement is found analytically, from the
    # sensor poses.
    with _stage(progress, "equality_sets", timings):
        pairs, set_ids = equality_sets_from_poses(true_poses[:, :2], world.spacing)

    metrics = {
        "exploration.events": explored.events,
        "exploration.state_changes": explored.state_changes,
        "exploration.compensated": explored.compensated,
        "exploration.state_changes_compensated": explored.state_changes_compensated,
        "exploration.missed_in_ring": len(explored.missed_in_ring),
        "pov.count": int(valid.sum()),
        "pov.invalid": int((~valid).sum()),
        "pov.max_pose_drift": _pose_drift(povs, true_poses),
        "pov.steps_median": float(np.median(sampled.steps[valid])) if valid.any() else 0.0,
    }
    for reason, count in sorted(explored.failures_by_reason.items()):
        metrics[f"exploration.failures.{reason}"] = int(count)
    arrays = {
        "motor_states": explored.motor_states[valid],
        "true_poses": true_poses,
        "grid_index": explored.grid_index[valid],
        "grid": world.grid,
        "grid_spacing": np.float64(world.spacing),
        "initial_motor_state": world.m0,
        "missed_in_ring": np.asarray(explored.missed_in_ring, dtype=int),
        "receptors": world.receptors,
        "initial_lights": world.initial_lights,
    }
    return StrategyOutput(povs=povs, pairs=np.asarray(pairs, dtype=int),
                          set_ids=np.asarray(set_ids, dtype=int),
                          true_positions=true_poses[:, :2].copy(), metrics=metrics,
                          arrays=arrays, timings_s=timings)


def _sample_points_of_view(motor_states: np.ndarray, cfg: dict, progress=None,
                           processes: int | None = None):
    """``sample_points_of_view`` of every motor state, in two forked
    processes (halves of the batch) when ``_can_fork``.

    Every operation of the walk is per POV, so the halves give the same bits
    as one batch (tests check it). Measured on the paper's 649 POVs: 6.0 s of
    one process, 4.4 s per half (each half walks until its longest loop closes).
    """
    from sensorispace_ros.core.paper.points_of_view import (PointsOfViewResult,
        sample_points_of_view)

    if processes is None:
        processes = min(2, os.cpu_count() or 1) if _can_fork() else 1
    motor_states = np.asarray(motor_states, dtype=float)
    if processes < 2 or len(motor_states) < 64:
        return sample_points_of_view(motor_states, progress=progress, **pov_params(cfg))
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    chunks = np.array_split(motor_states, processes)
    with ProcessPoolExecutor(max_workers=processes,
                             mp_context=multiprocessing.get_context("fork")) as pool:
        futures = [pool.submit(sample_points_of_view, chunk, **pov_params(cfg))
                   for chunk in chunks]
        parts = []
        for future in futures:
            parts.append(future.result())
            if progress is not None:
                progress(sum(len(part.samples) for part in parts), len(motor_states))
    return PointsOfViewResult(
        samples=np.concatenate([part.samples for part in parts]),
        valid=np.concatenate([np.asarray(part.valid) for part in parts]),
        reason=[reason for part in parts for reason in part.reason],
        steps=np.concatenate([part.steps for part in parts]),
        max_pose_drift=max(part.max_pose_drift for part in parts),
        winding=np.concatenate([part.winding for part in parts]))


def run_naive_strategy(cfg: dict, seed: int, progress=None) -> StrategyOutput:
    """Simulations 1 and 2 from the sensorimotor flow alone (issue #3)."""
    from sensorispace_ros.core.paper.exploration import build_world
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.naive.run import run_naive

    timings: dict = {}
    world = build_world(seed, world_params(cfg))
    params = NaiveParams(**cfg["naive"])
    start = time.perf_counter()
    result = run_naive(world, params, seed, progress)
    elapsed = time.perf_counter() - start
    timings.update({key: float(value) for key, value in getattr(result, "timings_s", {}).items()
                    if key in ("exploration", "points_of_view", "equality_sets")})
    timings.setdefault("exploration", elapsed - sum(timings.values()))
    # Ground-truth bookkeeping of the run (incl. the paper strategy for the
    # coverage denominator): timed, but not a stage of the agent.
    if "evaluation" in getattr(result, "timings_s", {}):
        timings["naive_ground_truth"] = float(result.timings_s["evaluation"])
    povs = np.asarray(result.povs)
    true_poses = np.asarray(result.true_poses)
    metrics = {"pov.count": len(povs),
               "pov.max_pose_drift": _pose_drift(povs, true_poses)}
    metrics.update({key: value for key, value in result.metrics.items()})
    arrays = {
        "motor_states": povs[:, 0],
        "true_poses": true_poses,
        "grid_index": np.asarray(result.grid_index, dtype=int),
        "grid": world.grid,
        "grid_spacing": np.float64(world.spacing),
        "initial_motor_state": world.m0,
        "receptors": world.receptors,
        "initial_lights": world.initial_lights,
    }
    return StrategyOutput(povs=povs, pairs=np.asarray(result.pairs, dtype=int),
                          set_ids=np.asarray(result.set_ids, dtype=int),
                          true_positions=true_poses[:, :2].copy(), metrics=metrics,
                          arrays=arrays, timings_s=timings)


def _pose_drift(povs: np.ndarray, true_poses: np.ndarray) -> float:
    """Largest pose error of any POV sample w.r.t. its POV's sensor pose (ground truth)."""
    from sensorispace_ros.core import arm

    if len(povs) == 0:
        return 0.0
    poses = arm.forward(povs)
    return float(np.max(arm.pose_error(poses, true_poses[:, None, :])))


# ---------------------------------------------------------------------------
# The agent's representation (no ground truth)


def cca_params(cfg: dict) -> dict:
    cca = cfg["representation"]["cca"]
    return {"n_epochs": cca["n_epochs"], "alpha0": cca["alpha0"], "lambda0": cca["lambda0"]}


def build_representation(povs: np.ndarray, pairs: np.ndarray, set_ids: np.ndarray, cfg: dict,
                         seed: int, progress=None, processes: int | None = None,
                         executor: Executor | None = None,
                         distance: np.ndarray | None = None) -> Representation:
    """Hausdorff metric, CCA before regularisation and the regularisation
    iterations, in 2-D and 3-D, from the agent's data only.

    ``distance``: the Hausdorff matrix of ``povs`` when the caller already has
    it (the representation node grows it while the POVs arrive,
    ``core.hausdorff.GrowingHausdorffMatrix``: the same bits); computed here
    otherwise.

    ``processes``: how many processes run the 2-D and 3-D chains (default:
    2 on a multi-core machine, when the caller can fork safely: see
    ``_can_fork``). ``executor``: the caller's own pool for the chains (a
    process that must not fork, e.g. ``start_chain_pool``'s), in place of
    ``processes``. The result depends on neither.
    """
    from sensorispace_ros.core.hausdorff import hausdorff_matrix

    povs = np.asarray(povs, dtype=float)
    if povs.ndim != 3 or povs.shape[2] != 4 or len(povs) < 4:
        raise ValueError(f"povs must have shape (P >= 4, N, 4), got {povs.shape}")
    if processes is not None and executor is not None:
        raise ValueError("processes and executor: give one of them, not both")
    if executor is not None:
        workers = len(DIMENSIONS)
    elif processes is None:
        workers = min(len(DIMENSIONS), os.cpu_count() or 1) if _can_fork() else 1
    else:
        workers = int(processes)
        if workers < 1:
            raise ValueError(f"processes must be >= 1, got {processes!r}")
    if distance is not None:
        distance = np.asarray(distance, dtype=float)
        if distance.shape != (len(povs), len(povs)):
            raise ValueError(f"distance must have shape ({len(povs)}, {len(povs)}), "
                             f"got {distance.shape}")
    timings: dict = {}
    with _stage(progress, "hausdorff", timings):
        if distance is None:
            distance = hausdorff_matrix(povs, progress=progress)

    # The 2-D and 3-D chains (CCA, then regularise -> CCA) are independent and
    # each draws from its own seeded streams, so two processes give the same
    # bits as one (issue #6: x1.3 at load 3, up to x2 on an idle 2-core machine).
    chains, block = {}, {}
    with _stage(progress, "cca_regularization", block, total=len(DIMENSIONS)):
        if executor is not None:
            _chains_in(executor, chains, distance, pairs, set_ids, cfg, seed, progress)
        elif workers > 1:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            context = multiprocessing.get_context("fork")
            with ProcessPoolExecutor(max_workers=min(workers, len(DIMENSIONS)),
                                     mp_context=context) as pool:
                _chains_in(pool, chains, distance, pairs, set_ids, cfg, seed, progress)
        else:
            for name, n_components in DIMENSIONS.items():
                chains[name] = _dimension_chain(distance, pairs, set_ids, cfg, seed, name,
                                                n_components)
                if progress is not None:
                    progress(len(chains), len(DIMENSIONS))
    before = {name: chain["before"] for name, chain in chains.items()}
    iterations = {name: chain["iterations"] for name, chain in chains.items()}
    spread = {name: chain["spread"] for name, chain in chains.items()}
    # Wall times that add up to the block's: "cca" the CCA before
    # regularisation (in parallel: until every chain had it), "regularization"
    # the rest. Each chain's own times are "cca_<dim>", "regularization_<dim>".
    cca_times = [chain["timings_s"]["cca"] for chain in chains.values()]
    timings["cca"] = max(cca_times) if workers > 1 else sum(cca_times)
    timings["regularization"] = block["cca_regularization"] - timings["cca"]
    for name, chain in chains.items():
        for step in ("cca", "regularization"):
            timings[f"{step}_{name}"] = chain["timings_s"][step]
    return Representation(distance=distance, before=before, iterations=iterations,
                          set_spread=spread, timings_s=timings)


def _chains_in(pool: Executor, chains: dict, distance: np.ndarray, pairs: np.ndarray,
               set_ids: np.ndarray, cfg: dict, seed: int, progress=None) -> None:
    """The 2-D and 3-D chains as tasks of ``pool``, into ``chains``."""
    futures = {name: pool.submit(_dimension_chain, distance, pairs, set_ids, cfg, seed, name,
                                 n_components)
               for name, n_components in DIMENSIONS.items()}
    for name, future in futures.items():
        chains[name] = future.result()
        if progress is not None:
            progress(len(chains), len(DIMENSIONS))


# What a chain worker imports, loaded once by the forkserver so that every
# worker forked from it starts with them (numba's import alone is ~1 s).
CHAIN_WORKER_MODULES = ("numpy", "scipy.linalg", "scipy.spatial.distance", "sklearn.base",
                        "sensorispace_ros.core.cca", "sensorispace_ros.core.regularize")
CHAIN_START_METHODS = ("forkserver", "spawn")


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
    pool = ProcessPoolExecutor(max_workers=len(DIMENSIONS), mp_context=context,
                               initializer=_chain_worker_started)
    try:
        # Submitted together, the warm-ups find no idle worker: one worker each.
        for future in [pool.submit(_warm_chain_worker) for _ in DIMENSIONS]:
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
    from sensorispace_ros.core.cca import CCA

    points = np.arange(16, dtype=float).reshape(8, 2) ** 1.5
    CCA(n_components=2, metric="precomputed", init="mds", n_epochs=1,
        random_state=0).fit_transform(squareform(pdist(points)))
    return os.getpid()


def _can_fork() -> bool:
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


def _dimension_chain(distance: np.ndarray, pairs: np.ndarray, set_ids: np.ndarray, cfg: dict,
                     seed: int, name: str, n_components: int) -> dict:
    """CCA of the Hausdorff metric, then the regularisation iterations, in
    ``n_components`` dimensions (a process of its own in build_representation)."""
    from sensorispace_ros.core.cca import CCA
    from sensorispace_ros.core.regularize import iterate_regularization, set_spread

    started = time.perf_counter()
    estimator = CCA(n_components=n_components, metric="precomputed", init="mds",
                    random_state=_random_state(seed, f"cca.{name}"), **cca_params(cfg))
    before = np.asarray(estimator.fit_transform(distance))
    cca_s = time.perf_counter() - started
    result = iterate_regularization(
        distance, pairs, set_ids, n_components=n_components,
        n_iterations=cfg["representation"]["regularization"]["iterations"],
        cca_params=cca_params(cfg), random_state=_random_state(seed, f"regularization.{name}"),
        init=None)
    # result.set_spread[k] is measured before iteration k's averaging
    # (k = 0: the Hausdorff metric); add the spread after the last one.
    spread = np.asarray([*result.set_spread, set_spread(result.distances, pairs, set_ids)],
                        dtype=float)
    return {"before": before,
            "iterations": np.stack([np.asarray(e) for e in result.embeddings]),
            "spread": spread,
            "timings_s": {"cca": cca_s,
                          "regularization": time.perf_counter() - started - cca_s}}


# ---------------------------------------------------------------------------
# Evaluation against ground truth


def evaluate(representation: Representation, true_positions: np.ndarray, povs: np.ndarray,
             cfg: dict, seed: int, progress=None) -> dict:
    """Ground-truth numbers of a representation (flat dotted keys).

    ``quality.<dim>.<stage>.*``: ``core.quality.quality_report`` plus
    ``neighbours_true_fraction``; ``metric.*.unit_step_cv``: spread of the
    internal lengths of equal external grid steps (Fig. 9 as a number);
    ``regularization.<dim>.set_spread``: spread of the equality sets'
    distances, first of the Hausdorff metric then after each iteration;
    ``reaching.<graph>.*``: straightness of Dijkstra paths between the same
    random start/target pairs in every graph, with its pruning radius and
    degrees; ``timings_s.reaching``. ``povs`` is accepted so callers hand
    over the whole run; no number here needs it yet.
    """
    from sensorispace_ros.core.quality import quality_report
    from sensorispace_ros.core.reach import reaching_evaluation

    true_positions = np.asarray(true_positions, dtype=float)
    metrics: dict[str, Any] = {}
    timings: dict = {}
    spacing = _grid_step(true_positions)
    external = pdist(true_positions)
    neighbours = _true_neighbour_pairs(true_positions, spacing)

    hausdorff_condensed = squareform(representation.distance, checks=False)
    metrics["metric.hausdorff.spearman"] = _spearman(hausdorff_condensed, external)
    metrics["metric.hausdorff.unit_step_cv"] = _unit_step_cv(representation.distance, neighbours)
    for dim in DIMENSIONS:
        for stage in STAGES:
            embedding = representation.embedding(dim, stage)
            prefix = f"quality.{dim}.{stage}"
            for key, value in quality_report(embedding, true_positions).items():
                metrics[f"{prefix}.{key}"] = value
            metrics[f"{prefix}.neighbours_true_fraction"] = _neighbours_true_fraction(
                embedding, true_positions)
            metrics[f"metric.{dim}.{stage}.unit_step_cv"] = _unit_step_cv(
                squareform(pdist(embedding)), neighbours)
        spread = representation.set_spread[dim]
        metrics[f"regularization.{dim}.set_spread"] = [float(v) for v in spread]

    reaching = cfg["representation"]["reaching"]
    options = {"n_pairs": reaching["pairs"], "max_degree": reaching["max_degree"],
               "radius": reaching["radius"]}
    # One stream for every representation: all are tested on the same pairs.
    reaching_seed = _random_state(seed, "reaching")
    with _stage(progress, "reaching", timings):
        graphs = {"hausdorff": representation.distance}
        for dim in DIMENSIONS:
            for stage in STAGES:
                graphs[f"{dim}.{stage}"] = squareform(pdist(representation.embedding(dim, stage)))
        for k, (name, distance) in enumerate(graphs.items()):
            result = reaching_evaluation(distance, true_positions, random_state=reaching_seed,
                                         **options)
            reached = [v for v in result["straightness"] if v is not None]
            degree = np.sum(distance < result["radius"], axis=1) - 1
            metrics.update({
                f"reaching.{name}.straightness_median": result["straightness_median"],
                f"reaching.{name}.straightness_p90": float(np.percentile(reached, 90))
                if reached else float("nan"),
                f"reaching.{name}.radius": result["radius"],
                f"reaching.{name}.degree_mean": float(np.mean(degree)),
                f"reaching.{name}.degree_max": int(np.max(degree)),
                f"reaching.{name}.graph_components": result["n_components"],
                f"reaching.{name}.unreachable": result["unreachable"],
            })
            if progress is not None:
                progress(k + 1, len(graphs))
    metrics["timings_s.reaching"] = timings["reaching"]
    return metrics


def _grid_step(positions: np.ndarray) -> float:
    """Median nearest-neighbour distance: the grid step of the sensor positions."""
    from scipy.spatial import cKDTree

    if len(positions) < 2:
        return 1.0
    distance, _ = cKDTree(positions).query(positions, k=2)
    return float(np.median(distance[:, 1]))


def _true_neighbour_pairs(positions: np.ndarray, spacing: float) -> np.ndarray:
    """POV pairs one grid step apart outside (the paper's Fig. 9 transitions)."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(positions).query_pairs(1.01 * spacing, output_type="ndarray")
    return np.asarray(pairs, dtype=int).reshape(-1, 2)


def _unit_step_cv(distance: np.ndarray, pairs: np.ndarray) -> float:
    """Coefficient of variation of the internal lengths of equal external grid
    steps: 0 for a metric as regular as the external one (paper Fig. 9)."""
    if len(pairs) == 0:
        return float("nan")
    lengths = distance[pairs[:, 0], pairs[:, 1]]
    return float(np.std(lengths) / np.mean(lengths))


def _neighbours_true_fraction(embedding: np.ndarray, positions: np.ndarray,
                              k: int = 4) -> float:
    """Fraction of POVs whose ``k`` nearest neighbours in the representation
    are also their ``k`` nearest outside (ties in the grid allowed)."""
    from scipy.spatial import cKDTree

    k = min(k, len(embedding) - 1)
    _, index = cKDTree(embedding).query(embedding, k=k + 1)
    true_kth, _ = cKDTree(positions).query(positions, k=k + 1)
    gap = np.linalg.norm(positions[index[:, 1:]] - positions[:, None, :], axis=-1)
    # Ties: compensated sensor positions sit ~1e-7 off the exact grid.
    return float(np.mean(np.all(gap <= true_kth[:, -1:] * (1.0 + 1e-3), axis=1)))


def _spearman(a: np.ndarray, b: np.ndarray) -> float:
    return float(spearmanr(a, b).statistic)


# ---------------------------------------------------------------------------
# The whole run


def reproduce(cfg: dict, strategy: str = "paper", seed: int | None = None,
              out_dir: str | Path = "results/run", progress=None) -> dict:
    """Run a strategy end to end; write metrics.json, arrays.npz, figures/*.png.

    Returns the metrics (nested dict, as written). ``seed`` overrides
    ``cfg["seed"]``.
    """
    if strategy not in STRATEGIES:
        raise ValueError(f"strategy must be one of {', '.join(STRATEGIES)}, got {strategy!r}")
    if seed is not None:
        cfg = config_mod.load_config(overrides={**config_mod.flatten(cfg), "seed": seed})
    else:
        cfg = config_mod.validate_config(cfg)
    seed = cfg["seed"]

    started = time.perf_counter()
    produced = run_strategy(cfg, strategy, seed, progress)
    representation = build_representation(produced.povs, produced.pairs, produced.set_ids, cfg,
                                           seed, progress)
    flat = dict(produced.metrics)
    flat.update(evaluate(representation, produced.true_positions, produced.povs, cfg, seed,
                         progress))
    timings = {**produced.timings_s, **representation.timings_s,
               "reaching": flat.pop("timings_s.reaching")}
    timings["total"] = time.perf_counter() - started
    arrays = {**produced.arrays, **run_arrays(produced, representation, cfg, seed)}
    return write_run(out_dir, flat, arrays, cfg, strategy, timings, progress)


def write_run(out_dir: str | Path, flat_metrics: dict, arrays: dict, cfg: dict, strategy: str,
              timings: dict, progress=None) -> dict:
    """Figures, arrays.npz and metrics.json of a finished run; returns the metrics.

    ``flat_metrics`` has dotted keys; ``timings`` go under ``timings_s``
    (figure drawing is timed as ``figures``, outside ``total``).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    timings = dict(timings)
    arrays = dict(arrays)
    if cfg["output"]["figures"]:
        from sensorispace_ros.offline import figures

        with _stage(progress, "figures", timings, total=len(figures.FIGURES)):
            arrays.update(_draw_figures(arrays, cfg, out_dir / FIGURES_DIR, progress))
    np.savez_compressed(out_dir / ARRAYS_FILE, **arrays)

    flat = dict(flat_metrics)
    pairs, set_ids = arrays["pairs"], arrays["set_ids"]
    flat.setdefault("equality_sets.count", int(len(np.unique(set_ids))))
    flat.setdefault("equality_sets.pairs", int(len(pairs)))
    flat.update({f"timings_s.{key}": value for key, value in timings.items()})
    flat["strategy"] = strategy
    flat["seed"] = cfg["seed"]
    metrics = nest(flat)
    metrics["config"] = config_mod.flatten(cfg)
    write_metrics(metrics, out_dir / METRICS_FILE)
    return metrics


def _examples_figure(cfg: dict, figures_dir: Path) -> dict:
    """Fig. 6 from its own POVs (``figure_examples``); returns those arrays."""
    from sensorispace_ros.offline import figures

    examples = figure_examples(cfg)
    figures.draw_all(examples, figures_dir, seed=cfg["seed"], only=[EXAMPLES_FIGURE])
    return examples


EXAMPLES_FIGURE = "fig06_point_of_view"


def _draw_figures(arrays: dict, cfg: dict, figures_dir: Path, progress=None) -> dict:
    """Every figure; returns the arrays of Fig. 6's example POVs.

    Fig. 6 samples POVs of its own (~2.5 s), so when ``_can_fork`` a forked
    process does it while this one draws the others (~5 s on the paper run).
    """
    from sensorispace_ros.offline import figures

    others = [name for name in figures.FIGURES if name != EXAMPLES_FIGURE]
    if not (_can_fork() and (os.cpu_count() or 1) > 1):
        examples = _examples_figure(cfg, figures_dir)
        figures.draw_all(arrays, figures_dir, seed=cfg["seed"], progress=progress, only=others)
        return examples
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=1,
                             mp_context=multiprocessing.get_context("fork")) as pool:
        future = pool.submit(_examples_figure, cfg, figures_dir)
        figures.draw_all(arrays, figures_dir, seed=cfg["seed"], progress=progress, only=others)
        return future.result()


def run_arrays(produced: StrategyOutput, representation: Representation, cfg: dict,
               seed: int) -> dict:
    """Everything needed to redraw the figures or re-evaluate, as arrays."""
    arrays = {
        "povs": np.asarray(produced.povs),
        "true_positions": np.asarray(produced.true_positions),
        "pairs": np.asarray(produced.pairs),
        "set_ids": np.asarray(produced.set_ids),
        "hausdorff": representation.distance,
        "config_json": np.asarray(json.dumps(cfg, sort_keys=True)),
        "seed": np.int64(seed),
    }
    for dim in DIMENSIONS:
        arrays[f"embedding_{dim}_before"] = representation.before[dim]
        arrays[f"embedding_{dim}_iterations"] = representation.iterations[dim]
        arrays[f"set_spread_{dim}"] = representation.set_spread[dim]
    return arrays


def representation_from_arrays(arrays) -> Representation:
    """The ``Representation`` stored in a run's arrays (``run_arrays`` names)."""
    timings = {}
    if "timings_s_json" in arrays:
        timings = json.loads(str(np.asarray(arrays["timings_s_json"])))
    return Representation(
        distance=np.asarray(arrays["hausdorff"]),
        before={dim: np.asarray(arrays[f"embedding_{dim}_before"]) for dim in DIMENSIONS},
        iterations={dim: np.asarray(arrays[f"embedding_{dim}_iterations"]) for dim in DIMENSIONS},
        set_spread={dim: np.asarray(arrays[f"set_spread_{dim}"]) for dim in DIMENSIONS},
        timings_s=timings)


def ground_truth_from_motor(povs: np.ndarray, cfg: dict) -> dict:
    """Ground truth of POVs recorded without it (a graph run): sensor poses
    from the forward model, object grid position from the tip displacement
    since the initial pose. Evaluation only."""
    from sensorispace_ros.core import arm
    from sensorispace_ros.core.world import grid_spacing, position_grid

    povs = np.asarray(povs, dtype=float)
    true_poses = arm.forward(povs[:, 0])
    m0 = np.asarray(cfg["arm"]["initial_motor_state"], dtype=float)
    world = cfg["world"]
    grid = position_grid(world["grid_half_width"], world["grid_count"])
    spacing = grid_spacing(world["grid_half_width"], world["grid_count"])
    displacement = true_poses[:, :2] - arm.forward(m0)[:2]
    nearest = np.argmin(np.linalg.norm(displacement[:, None, :] - grid[None], axis=-1), axis=1)
    on_grid = np.linalg.norm(grid[nearest] - displacement, axis=1) < spacing / 4
    return {"true_poses": true_poses, "true_positions": true_poses[:, :2].copy(),
            "motor_states": povs[:, 0], "grid": grid, "grid_spacing": np.float64(spacing),
            "grid_index": np.where(on_grid, nearest, -1), "initial_motor_state": m0}


def evaluate_graph_run(arrays, cfg: dict, results_dir: str | Path, metrics: dict | None = None,
                       strategy: str = "naive", progress=None) -> dict:
    """metrics.json, arrays.npz and figures of a representation built elsewhere
    (the ROS representation node, a bag): same evaluation as ``reproduce``.

    ``arrays`` holds the ``run_arrays`` names (``povs``, ``pairs``,
    ``set_ids``, ``hausdorff``, ``embedding_*``, ``set_spread_*``);
    ``true_positions`` and the exploration arrays are taken from it when
    present, else computed from the forward model. ``metrics``: dotted
    counters known to the caller (``exploration.*``, ``naive.*``, timings as
    ``timings_s.*``).
    """
    cfg = config_mod.validate_config(cfg)
    arrays = {key: np.asarray(value) for key, value in dict(arrays).items()}
    representation = representation_from_arrays(arrays)
    povs = arrays["povs"]
    truth = ground_truth_from_motor(povs, cfg)
    for key, value in truth.items():
        arrays.setdefault(key, value)
    flat = {key: value for key, value in (metrics or {}).items()
            if not key.startswith("timings_s.")}
    timings = {key[len("timings_s."):]: value for key, value in (metrics or {}).items()
               if key.startswith("timings_s.")}
    for key, value in representation.timings_s.items():
        timings.setdefault(key, value)
    flat.setdefault("pov.count", int(len(povs)))
    flat.setdefault("pov.max_pose_drift", _pose_drift(povs, truth["true_poses"]))
    evaluated = evaluate(representation, arrays["true_positions"], povs, cfg, cfg["seed"],
                         progress)
    timings["reaching"] = evaluated.pop("timings_s.reaching")
    flat.update(evaluated)
    produced = StrategyOutput(povs=povs, pairs=arrays["pairs"], set_ids=arrays["set_ids"],
                              true_positions=arrays["true_positions"], metrics={}, arrays={},
                              timings_s={})
    arrays.update(run_arrays(produced, representation, cfg, cfg["seed"]))
    return write_run(results_dir, flat, arrays, cfg, strategy, timings, progress)


def figure_examples(cfg: dict) -> dict:
    """POVs drawn only for Fig. 6: the initial motor state's POV, and POVs
    of sensor poses along the x axis (one of them inside |tip| < 1)."""
    from sensorispace_ros.core import arm
    from sensorispace_ros.core.paper.points_of_view import project_onto_pose, sample_points_of_view

    m0 = np.asarray(cfg["arm"]["initial_motor_state"], dtype=float)
    reach = np.array([0.6, 1.3, 1.8, 2.3, 2.8])
    # Start each from a folded arm pointing along x, projected onto its pose.
    guess = np.array([[-1.2, 1.6, -0.4 - 0.2 * k, 0.0] for k in range(len(reach))])
    guess[:, 3] = -np.sum(guess[:, :3], axis=1) + np.pi / 2     # eye looking up
    targets = np.stack([reach, np.zeros_like(reach), np.full_like(reach, np.pi / 2)], axis=1)
    starts, error = project_onto_pose(guess[:, None, :], targets)
    starts = starts[:, 0][error[:, 0] < 1e-9]
    sampled = sample_points_of_view(np.vstack([m0[None, :], starts]), **pov_params(cfg))
    tips = np.hypot(*arm.forward(sampled.samples[1:, 0])[:, :2].T)
    return {"pov_example": sampled.samples[0],
            "pov_examples_x": sampled.samples[1:],
            "pov_examples_x_valid": np.asarray(sampled.valid[1:], dtype=bool),
            "pov_examples_x_reach": tips}


# ---------------------------------------------------------------------------
# metrics.json


def nest(flat: dict) -> dict:
    """Dotted keys -> nested dicts (``"a.b": 1`` -> ``{"a": {"b": 1}}``)."""
    out: dict = {}
    for key, value in flat.items():
        node = out
        parts = key.split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ValueError(f"metric {key!r} collides with a value at {part!r}")
        if isinstance(node.get(parts[-1]), dict):
            raise ValueError(f"metric {key!r} collides with a group of metrics")
        node[parts[-1]] = value
    return out


def flatten_metrics(metrics: dict, prefix: str = "") -> dict:
    """Nested metrics -> dotted keys (the same rule as the config's parameter names)."""
    return config_mod.flatten(metrics, prefix)


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_jsonable(v) for v in np.asarray(value, dtype=object).tolist()] \
            if isinstance(value, np.ndarray) else [_jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        if not math.isfinite(value):
            return None                   # JSON has no NaN / inf
        return float(f"{value:.{FLOAT_DIGITS}g}")
    return value


def write_metrics(metrics: dict, path: str | Path) -> None:
    """Sorted keys, floats rounded to ``FLOAT_DIGITS`` significant digits."""
    path = Path(path)
    text = json.dumps(_jsonable(metrics), sort_keys=True, indent=2) + "\n"
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def read_metrics(path: str | Path) -> dict:
    """metrics.json of a run directory (or the file itself)."""
    path = Path(path)
    if path.is_dir():
        path = path / METRICS_FILE
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such metrics file") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
