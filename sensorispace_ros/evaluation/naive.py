"""A naive run's own products (its compensations, POVs, equality sets)
against ground truth (``ground_truth``), offline or from the graph; never in
the agent or the representation. Every key is ``exploration.*``, ``pov.*`` or
``naive.*`` of metrics.json.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from sensorispace_ros.core import arm
from sensorispace_ros.core.naive.records import STAGES as NAIVE_STAGES
from sensorispace_ros.core.naive.records import SEARCH_FIELDS, STRUCTURE_FIELDS, NaiveAgentRecords
from sensorispace_ros.core.world import REDISTRIBUTION
from sensorispace_ros.evaluation import rotations
from sensorispace_ros.evaluation.ground_truth import (NaiveGroundTruth, RunTruth,
                                                      naive_truth_of_changes, naive_truth_of_run)
from sensorispace_ros.offline.strategies import StrategyOutput, pose_drift


@dataclass
class NaiveEvaluation:
    """Ground-truth numbers of a naive run (``exploration.*``, ``pov.*``,
    ``naive.*``), the sensor pose ``(P, 3)`` of each POV and the object's
    grid position ``(P,)`` when it was found (-1 for the initial POV)."""

    metrics: dict
    true_poses: np.ndarray
    grid_index: np.ndarray


def evaluate_naive_run(run, world, paper_positions: np.ndarray | None = None
                       ) -> NaiveEvaluation:
    """``evaluate_naive_records`` of an offline run (``core.naive.run.run_naive``
    in ``world``); ``paper_positions`` as ``ground_truth.naive_truth_of_run``'s."""
    records = NaiveAgentRecords.from_agent(run.agent)
    return evaluate_naive_records(records, naive_truth_of_run(run, world, paper_positions))


def join_naive_run(produced: StrategyOutput, truth: RunTruth) -> StrategyOutput:
    """An offline naive run (``offline.strategies.run_naive_strategy``) joined
    with ground truth: its ``pov.*``, ``exploration.*`` and ``naive.*`` numbers,
    true positions and figure arrays, timed as ``naive_ground_truth`` (not a
    stage of the agent)."""
    world, result = truth.world, produced.naive_run
    started = time.perf_counter()
    evaluated = evaluate_naive_run(result, world, truth.paper_positions)
    if result.clock is not None:
        from sensorispace_ros.evaluation.clock import clock_metrics
        evaluated.metrics.update(clock_metrics(result, world))
    seconds = time.perf_counter() - started
    povs = produced.povs
    true_poses = np.asarray(evaluated.true_poses)
    produced.timings_s["naive_ground_truth"] = seconds
    produced.metrics = {"pov.count": len(povs),
                        "pov.max_pose_drift": pose_drift(povs, true_poses, world.arm),
                        **evaluated.metrics, **produced.metrics,
                        "naive.timings_s.evaluation": seconds}
    produced.true_positions = true_poses[:, :2].copy()
    produced.arrays = {
        "motor_states": povs[:, 0],
        "true_poses": true_poses,
        "grid_index": np.asarray(evaluated.grid_index, dtype=int),
        "grid": world.grid,
        "grid_spacing": np.float64(world.spacing),
        "initial_motor_state": world.m0,
        "receptors": world.receptors,
        "initial_lights": world.initial_lights,
    }
    return produced


def naive_metrics(records: NaiveAgentRecords, truth: RunTruth, changes: int, poses: np.ndarray,
                  recorded: dict | None = None) -> NaiveEvaluation:
    """``evaluate_naive_records`` of a graph run: ``changes`` is ``/agent/done``'s
    (``end/<k>`` closes a run of k - 1 changes), ``recorded`` the changes a bag
    holds (``ground_truth.naive_truth_of_changes``)."""
    evaluated = evaluate_naive_records(
        records, naive_truth_of_changes(truth, int(changes) - 1, poses, recorded))
    evaluated.grid_index = np.asarray(evaluated.grid_index, dtype=int)
    return evaluated


def evaluate_naive_records(records: NaiveAgentRecords, truth: NaiveGroundTruth
                           ) -> NaiveEvaluation:
    """Ground-truth numbers of what a naive agent produced, offline or in the ROS graph."""
    povs = records.povs
    true_poses = np.asarray(truth.true_poses, dtype=float).reshape(-1, 3)
    if len(true_poses) != len(povs):
        raise ValueError(f"truth.true_poses: {len(true_poses)} poses for {len(povs)} POVs")
    unknown = (set(records.queries_by_stage) | set(records.calls_by_stage)) - set(NAIVE_STAGES)
    if unknown:
        raise ValueError(f"records.queries_by_stage: stages {sorted(unknown)} not in NAIVE_STAGES")
    kinds = truth.kinds
    metrics = {
        "exploration.events": len(kinds) - 1,
        "exploration.state_changes": int(sum(k == REDISTRIBUTION for k in kinds)),
        "exploration.compensated": int(records.compensated),
        "pov.count": int(len(povs)),
        "pov.max_pose_drift": pose_drift(povs, true_poses, truth.arm),
        **_query_numbers(records),
        **_compensation_numbers(records, truth),
        **_coverage_numbers(true_poses, truth),
        **_set_numbers(true_poses, records.pairs, records.set_ids),
        **_structure_numbers(records),
    }
    metrics["exploration.state_changes_compensated"] = metrics["naive.state_changes_accepted"]
    # The object's grid position when each POV was found (event 0: the start).
    grid_index = (np.asarray(truth.grid_index)[np.asarray(records.pov_events, dtype=int)]
                  if len(povs) else np.zeros(0, dtype=int))
    return NaiveEvaluation(metrics, true_poses, grid_index)


def _query_numbers(records: NaiveAgentRecords) -> dict:
    """What the agent spent: sensation queries and body calls, per POV,
    per compensation and per stage."""
    pov_q = np.asarray(records.pov_queries, dtype=float)
    n_comp = len(records.compensation_event)
    numbers = {
        "naive.queries_total": int(records.queries_total),
        "naive.calls_total": int(records.calls_total),
        "naive.queries_per_pov": float(pov_q.mean()) if len(pov_q) else 0.0,
        "naive.queries_per_pov_max": int(pov_q.max()) if len(pov_q) else 0,
        # Every motor state probed, per POV found: on a robot, every one is a move.
        "naive.queries_total_per_pov":
            records.queries_total / len(pov_q) if len(pov_q) else float(records.queries_total),
        # Every row of an event that found a compensation except its POV walks
        # (sweep, rank tests, searches, rest command), averaged over those events.
        "naive.queries_per_compensation":
            records.compensation_queries / records.compensated if records.compensated else 0.0,
        # Search rows (LM) of the whole run per accepted compensation.
        "naive.search_queries_per_compensation":
            records.queries_by_stage.get("compensation", 0) / max(n_comp, 1),
    }
    for stage in NAIVE_STAGES:
        numbers[f"naive.queries_by_stage.{stage}"] = int(records.queries_by_stage.get(stage, 0))
    for stage in NAIVE_STAGES:
        numbers[f"naive.calls_by_stage.{stage}"] = int(records.calls_by_stage.get(stage, 0))
    # Search ends refused under noise (core.naive.known_loops).
    numbers.update({f"naive.{name}": int(getattr(records, name)) for name in SEARCH_FIELDS})
    # POVs moved onto one lattice at the end (core.naive.pov_relaxation).
    numbers["naive.povs_relaxed"] = int(records.povs_relaxed)
    return numbers


def _structure_numbers(records: NaiveAgentRecords) -> dict:
    """``naive.pose_rank``, ``naive.pov_dim``, ... : what the agent measured of its body."""
    if records.pose_rank < 0:
        return {}
    return {f"naive.{name}": getattr(records, name) for name in STRUCTURE_FIELDS}


def _compensation_numbers(records: NaiveAgentRecords, truth: NaiveGroundTruth) -> dict:
    """Each accepted compensation against the pose its anchor asks for, and
    against the changes it spans (light layout, event kind)."""
    events = records.compensation_event
    anchors = records.compensation_anchor_event
    n_comp = len(events)
    error = np.zeros(0)
    if n_comp and truth.orientations is not None:
        target = rotations.compensation_targets(
            truth.arm.forward(records.compensation_anchor_motor_state), truth.centers[anchors],
            truth.centers[events], truth.orientations[events] - truth.orientations[anchors])
        error = arm.pose_error(truth.arm.forward(records.compensation_motor_state), target)
    elif n_comp:
        target = truth.arm.forward(records.compensation_anchor_motor_state)
        target[:, :2] += truth.centers[events] - truth.centers[anchors]
        error = arm.pose_error(truth.arm.forward(records.compensation_motor_state), target)
    return {
        "naive.wrong_poses": int(np.sum(error > truth.pose_tolerance)),
        "naive.worst_pose_error": float(np.max(error)) if n_comp else 0.0,
        # Pose precision of the accepted compensations (right or wrong).
        "naive.pose_error_median": float(np.median(error)) if n_comp else 0.0,
        "naive.pose_error_p95": float(np.percentile(error, 95)) if n_comp else 0.0,
        "naive.state_changes_accepted": int(sum(truth.kinds[t] == REDISTRIBUTION
                                                for t in events)),
        "naive.accepted_across_redistribution": int(np.sum(truth.layout[events]
                                                           != truth.layout[anchors])),
        "naive.compensations_accepted": int(n_comp),
        "naive.compensations_searched": int(np.sum(records.compensation_searched)),
    }


def _coverage_numbers(true_poses: np.ndarray, truth: NaiveGroundTruth) -> dict:
    """Distinct compensated sensor positions over the number the paper
    strategy compensates, and the eye's orientation error.

    The naive agent's positions need not be the paper's: an anchor recorded
    while the object is on the grid gives positions p0 + (grid differences),
    the start's anchor (object at the off-grid initial centre) gives the
    paper's p0 + (grid - centre). ``coverage_of_paper_positions`` counts the
    paper's positions reached.
    """
    from scipy.spatial import cKDTree

    if truth.paper_poses is not None:
        pose0 = truth.arm.forward(truth.initial_motor_state)
        return {**rotations.pose_coverage(true_poses, truth.paper_poses, truth.pose_tolerance),
                "naive.max_orientation_error": rotations.orientation_class_error(
                    true_poses[:, 2], pose0[2], truth.rotation_count)}
    paper_positions = truth.paper_positions
    distinct, covered, orientation_error = 0, 0, 0.0
    if len(true_poses):
        pairs_close = cKDTree(true_poses[:, :2]).query_pairs(truth.pose_tolerance,
                                                             output_type="ndarray")
        duplicate = np.zeros(len(true_poses), dtype=bool)
        duplicate[pairs_close.max(axis=1) if len(pairs_close) else []] = True
        distinct = int(np.sum(~duplicate))
        if len(paper_positions):
            distance, _ = cKDTree(true_poses[:, :2]).query(paper_positions, k=1)
            covered = int(np.sum(distance <= truth.pose_tolerance))
        pose0 = truth.arm.forward(truth.initial_motor_state)
        orientation_error = float(np.max(np.abs(arm.wrap_angle(true_poses[:, 2] - pose0[2]))))
    return {
        "naive.coverage": distinct / max(len(paper_positions), 1),
        "naive.distinct_positions": distinct,
        "naive.duplicate_povs": int(len(true_poses) - distinct),
        "naive.paper_positions": int(len(paper_positions)),
        "naive.coverage_of_paper_positions": covered / max(len(paper_positions), 1),
        "naive.max_orientation_error": orientation_error,
    }


def _set_numbers(true_poses: np.ndarray, pairs: np.ndarray, set_ids: np.ndarray) -> dict:
    """Equality sets: how many, and how far a member's true displacement is
    from its set's first member's."""
    set_deviation = 0.0
    if len(pairs):
        displacement = true_poses[pairs[:, 1], :2] - true_poses[pairs[:, 0], :2]
        _, first, inverse = np.unique(set_ids, return_index=True, return_inverse=True)
        reference = displacement[first[inverse.reshape(-1)]]
        set_deviation = float(np.max(np.abs(displacement - reference)))
    return {
        "naive.equality_sets": int(len(np.unique(set_ids))),
        "naive.equality_pairs": int(len(pairs)),
        "naive.equality_set_max_deviation": set_deviation,
    }
