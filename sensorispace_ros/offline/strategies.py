"""Simulations 1 and 2 by one of the two strategies, as a ``StrategyOutput``.

``paper``: the paper's analytic shortcuts (``core.paper``). ``naive``: the
naive agent driven through the seeded schedule (``core.naive.run``), its
products then joined with ground truth by the evaluator. Either way the
agent's own data (points of view, equality sets) are kept apart from the
ground truth and figure material.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from sensorispace_ros.bodies import run_world
from sensorispace_ros.offline.chain_pool import can_fork
from sensorispace_ros.offline.timing import timed_stage

STRATEGIES = ("paper", "naive")


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
    true_positions: np.ndarray | None  # (P, 2) ground truth sensor positions (evaluator's)
    metrics: dict                    # dotted keys: exploration.*, pov.*, naive.*, ...
    arrays: dict                     # figure / re-evaluation material
    timings_s: dict
    world: Any = None                # the run's world (core.run_world), when simulated
    naive_run: Any = None            # core.naive.run.NaiveRunResult, until the evaluator joins it


def pov_params(cfg: dict) -> dict:
    """``core.paper.points_of_view.sample_points_of_view`` options from the configuration."""
    pov = cfg["pov"]
    return {"step": pov["step"], "n_samples": pov["n_samples"],
            "n_samples_2d": pov["n_samples_2d"],
            "min_steps": pov["min_steps"], "close_tol": pov["close_tol"]}


def run_strategy(cfg: dict, strategy: str, seed: int, progress=None) -> StrategyOutput:
    if strategy == "paper":
        return run_paper(cfg, seed, progress)
    if strategy == "naive":
        return run_naive_strategy(cfg, seed, progress)
    raise ValueError(f"strategy must be one of {', '.join(STRATEGIES)}, got {strategy!r}")


def run_paper(cfg: dict, seed: int, progress=None) -> StrategyOutput:
    """Simulations 1 and 2 with the paper's analytic shortcuts, on the
    configuration's body (``arm.*``): POVs in its motor unit."""
    from sensorispace_ros.core.paper.equality_sets import (equality_sets_by_orientation,
                                                           equality_sets_from_poses)
    from sensorispace_ros.core.paper.exploration import explore_paper

    timings: dict = {}
    with timed_stage(progress, "exploration", timings):
        world = run_world(cfg, seed)
        explored = explore_paper(
            m0=world.m0, grid=world.grid, events=world.events,
            initial_center=world.initial_center, threshold=cfg["compensation"]["threshold"],
            compensation_options={"initial_simplex_size": cfg["compensation"]["initial_simplex"]},
            progress=progress, body_arm=world.arm)
    with timed_stage(progress, "points_of_view", timings):
        sampled = _sample_points_of_view(explored.motor_states, cfg, progress,
                                         body_arm=world.arm)
    valid = np.asarray(sampled.valid, dtype=bool)
    povs = sampled.samples[valid]
    true_poses = explored.true_poses[valid]
    # Simulation 2 (paper Sec. 5.1, "optimized simulation setting"): the
    # compensating POV of a displacement is found analytically, from the
    # sensor poses.
    with timed_stage(progress, "equality_sets", timings):
        if int(world.params.get("rotation_count", 0)) >= 2:
            pairs, set_ids = equality_sets_by_orientation(true_poses, world.spacing)
        else:
            pairs, set_ids = equality_sets_from_poses(true_poses[:, :2], world.spacing)
    return StrategyOutput(povs=povs, pairs=np.asarray(pairs, dtype=int),
                          set_ids=np.asarray(set_ids, dtype=int),
                          true_positions=true_poses[:, :2].copy(),
                          metrics=_paper_metrics(explored, sampled, valid, povs, true_poses,
                                                 world.arm),
                          arrays=_paper_arrays(world, explored, valid, true_poses),
                          timings_s=timings, world=world)


def _paper_metrics(explored, sampled, valid: np.ndarray, povs: np.ndarray,
                   true_poses: np.ndarray, body_arm) -> dict:
    metrics = {
        "exploration.events": explored.events,
        "exploration.state_changes": explored.state_changes,
        "exploration.compensated": explored.compensated,
        "exploration.state_changes_compensated": explored.state_changes_compensated,
        "exploration.missed_in_ring": len(explored.missed_in_ring),
        "pov.count": int(valid.sum()),
        "pov.invalid": int((~valid).sum()),
        "pov.max_pose_drift": pose_drift(povs, true_poses, body_arm),
        "pov.steps_median": float(np.median(sampled.steps[valid])) if valid.any() else 0.0,
    }
    for reason, count in sorted(explored.failures_by_reason.items()):
        metrics[f"exploration.failures.{reason}"] = int(count)
    return metrics


def _paper_arrays(world, explored, valid: np.ndarray, true_poses: np.ndarray) -> dict:
    return {
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


def _sample_points_of_view(motor_states: np.ndarray, cfg: dict, progress=None,
                           processes: int | None = None, body_arm=None):
    """``sample_points_of_view`` of every motor state of ``body_arm`` (the
    paper arm by default), in two forked processes (halves of the batch)
    when ``can_fork``.

    Every operation of the samplers is per POV, so the halves give the same
    bits as one batch (tests check it); each half walks until its longest
    loop closes.
    """
    from sensorispace_ros.core.paper.points_of_view import (PointsOfViewResult,
        sample_points_of_view)

    from sensorispace_ros.core.arm import PAPER_ARM

    options = {**pov_params(cfg), "body_arm": PAPER_ARM if body_arm is None else body_arm}
    if processes is None:
        processes = min(2, os.cpu_count() or 1) if can_fork() else 1
    motor_states = np.asarray(motor_states, dtype=float)
    if processes < 2 or len(motor_states) < 64:
        return sample_points_of_view(motor_states, progress=progress, **options)
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    chunks = np.array_split(motor_states, processes)
    with ProcessPoolExecutor(max_workers=processes,
                             mp_context=multiprocessing.get_context("fork")) as pool:
        futures = [pool.submit(sample_points_of_view, chunk, **options)
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
    """Simulations 1 and 2 from the sensorimotor flow alone: the agent's own
    data and counters. Ground truth (true positions, ``pov.*``, the naive
    agent's ``naive.*`` against truth, figure arrays) is joined by the
    evaluator (``evaluation.naive.join_naive_run``) from ``naive_run``."""
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.clocked_run import run_on_clock

    world = run_world(cfg, seed)
    params = NaiveParams(**cfg["naive"])
    start = time.perf_counter()
    result = run_on_clock(world, params, cfg["world"]["clock"],
                          interval=cfg["world"]["change_interval"], progress=progress)
    elapsed = time.perf_counter() - start
    timings = {key: float(value) for key, value in result.timings_s.items()
               if key in ("exploration", "points_of_view", "equality_sets")}
    timings.setdefault("exploration", elapsed - sum(timings.values()))
    return StrategyOutput(povs=np.asarray(result.povs), pairs=np.asarray(result.pairs, dtype=int),
                          set_ids=np.asarray(result.set_ids, dtype=int), true_positions=None,
                          metrics=dict(result.metrics), arrays={}, timings_s=timings,
                          world=world, naive_run=result)


def pose_drift(povs: np.ndarray, true_poses: np.ndarray, body_arm=None) -> float:
    """Largest pose error of any POV sample w.r.t. its POV's sensor pose
    (ground truth, by ``body_arm``'s forward model; the paper arm's by default)."""
    from sensorispace_ros.core.arm import PAPER_ARM

    body_arm = PAPER_ARM if body_arm is None else body_arm
    if len(povs) == 0:
        return 0.0
    poses = body_arm.forward(povs)
    return float(np.max(body_arm.pose_error(poses, true_poses[:, None, :])))
