"""Evaluation of a run: the agent's representation and products against ground truth.

Every run takes one path, ``evaluate_output``: the offline run
(``reproduce``), a graph run (``evaluate_run``: from the bag through
``recording.analyze``, or from what the representation node wrote through
``evaluate_graph_run``), and the sweep's runs. It computes the numbers of
``evaluate`` and writes the run directory (``run_files.write_run``).

A naive run's own products (its compensations, POVs, equality sets) are
judged by ``evaluate_naive_records``, offline or from the graph, against
ground truth joined by ``ground_truth``; never in the agent or the
representation.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sensorispace_ros import config as config_mod
from sensorispace_ros.core import arm
from sensorispace_ros.core.arm import PAPER_ARM, Arm
from sensorispace_ros.core.naive.records import STAGES as NAIVE_STAGES
from sensorispace_ros.core.naive.records import STRUCTURE_FIELDS, NaiveAgentRecords
from sensorispace_ros.core.world import REDISTRIBUTION
from sensorispace_ros.offline.ground_truth import (NaiveGroundTruth, body_truth,
                                                   ground_truth_from_motor,
                                                   naive_truth_of_changes, naive_truth_of_run)
from sensorispace_ros.offline.representation import (STAGES, Representation,
                                                     random_state)
from sensorispace_ros.offline.run_files import representation_from_arrays, run_arrays, write_run
from sensorispace_ros.offline.strategies import StrategyOutput, pose_drift
from sensorispace_ros.offline.timing import timed_stage

# A compensating pose further than this from the pose its anchor asks for is wrong;
# two POVs closer than this are one sensor position.
WRONG_POSE_TOL = 1e-3


# ---------------------------------------------------------------------------
# The representation against the true sensor positions


def evaluate(representation: Representation, true_positions: np.ndarray, povs: np.ndarray,
             cfg: dict, seed: int, progress=None) -> dict:
    """Ground-truth numbers of a representation (flat dotted keys).

    ``quality.<dim>.<stage>.*``: ``core.quality.quality_report`` plus
    ``neighbours_true_fraction``; ``metric.*.unit_step_cv``: spread of the
    internal lengths of equal external grid steps (Fig. 9 as a number);
    ``metric.*.diagonal_ratio``: internal length of the (+1, +1) grid
    diagonals over the (+1, -1) ones (Fig. 13 as a number, 1 = consistent);
    ``exploration.missed_in_ring``: working-ring positions no POV covers
    (Fig. 7a's red outlines, ``missed_ring_positions``);
    ``topology.<space>.*``: Betti numbers of the true positions, the
    Hausdorff metric and every embedding (``core.topology``), timed as
    ``timings_s.topology``;
    ``regularization.<dim>.set_spread``: spread of the equality sets'
    distances, first of the Hausdorff metric then after each iteration;
    ``reaching.<graph>.*``: straightness of Dijkstra paths between the same
    random start/target pairs in every graph, with its pruning radius and
    degrees; ``timings_s.reaching``. ``povs`` is accepted so callers hand
    over the whole run; no number here needs it yet.
    """
    true_positions = np.asarray(true_positions, dtype=float)
    metrics = _metric_numbers(representation, true_positions)
    from sensorispace_ros.core.world import grid_spacing

    step = grid_spacing(cfg["world"]["grid_half_width"], cfg["world"]["grid_count"])
    metrics["exploration.missed_in_ring"] = len(missed_ring_positions(
        true_positions, step, Arm.from_config(cfg["arm"]).working_ring))
    timings: dict = {}
    with timed_stage(progress, "topology", timings):
        metrics.update(_topology_numbers(representation, true_positions))
    metrics["timings_s.topology"] = timings["topology"]
    with timed_stage(progress, "reaching", timings):
        metrics.update(_reaching_numbers(representation, true_positions, cfg, seed, progress))
    metrics["timings_s.reaching"] = timings["reaching"]
    return metrics


def _metric_numbers(representation: Representation, true_positions: np.ndarray) -> dict:
    """``metric.*``, ``quality.*`` and ``regularization.*`` of ``evaluate``."""
    from scipy.spatial.distance import pdist, squareform

    from sensorispace_ros.core.quality import quality_report
    from sensorispace_ros.core.sensor_grid import diagonal_ratio

    metrics: dict[str, Any] = {}
    spacing = _grid_step(true_positions)
    external = pdist(true_positions)
    neighbours = _true_neighbour_pairs(true_positions, spacing)
    hausdorff_condensed = squareform(representation.distance, checks=False)
    metrics["metric.hausdorff.spearman"] = _spearman(hausdorff_condensed, external)
    metrics["metric.hausdorff.unit_step_cv"] = _unit_step_cv(representation.distance, neighbours)
    metrics["metric.hausdorff.diagonal_ratio"] = diagonal_ratio(representation.distance,
                                                                true_positions, spacing)
    for dim in representation.before:
        for stage in STAGES:
            embedding = representation.embedding(dim, stage)
            prefix = f"quality.{dim}.{stage}"
            for key, value in quality_report(embedding, true_positions).items():
                metrics[f"{prefix}.{key}"] = value
            metrics[f"{prefix}.neighbours_true_fraction"] = _neighbours_true_fraction(
                embedding, true_positions)
            internal = squareform(pdist(embedding))
            metrics[f"metric.{dim}.{stage}.unit_step_cv"] = _unit_step_cv(internal, neighbours)
            metrics[f"metric.{dim}.{stage}.diagonal_ratio"] = diagonal_ratio(
                internal, true_positions, spacing)
        spread = representation.set_spread[dim]
        metrics[f"regularization.{dim}.set_spread"] = [float(v) for v in spread]
    return metrics


def topology_spaces(representation: Representation, true_positions: np.ndarray) -> dict:
    """The distance matrices ``topology.<space>`` measures: ``truth`` (the
    true positions, evaluation only), ``hausdorff`` and ``<dim>.<stage>``."""
    from sensorispace_ros.core.topology import euclidean_distances

    spaces = {"truth": euclidean_distances(true_positions), "hausdorff": representation.distance}
    for dim in representation.before:
        for stage in STAGES:
            spaces[f"{dim}.{stage}"] = euclidean_distances(representation.embedding(dim, stage))
    return spaces


def _topology_numbers(representation: Representation, true_positions: np.ndarray) -> dict:
    """``topology.<space>.*`` of ``evaluate`` (``core.topology.topology_report``)."""
    from sensorispace_ros.core.topology import topology_report

    return {f"topology.{space}.{key}": value
            for space, distance in topology_spaces(representation, true_positions).items()
            for key, value in topology_report(distance).items()}


def missed_ring_positions(true_positions: np.ndarray, spacing: float,
                          ring: tuple = PAPER_ARM.working_ring) -> np.ndarray:
    """``(M, 2)`` sensor positions of the arm's working ring that no POV
    covers, on the lattice most POVs lie on (``core.sensor_grid``): the
    positions that should have been compensated but were not, for any
    strategy. Fig. 7a outlines them. ``spacing`` is the object grid's step
    (the world's): on a fine grid the compensations' pose errors make the
    positions' median neighbour distance a step that is off by enough to
    slide the lattice's far positions off their POVs."""
    from sensorispace_ros.core.sensor_grid import missed_in_ring

    positions = np.asarray(true_positions, dtype=float).reshape(-1, 2)
    if len(positions) < 2:
        return np.zeros((0, 2))
    return missed_in_ring(positions, spacing, ring)


def _reaching_numbers(representation: Representation, true_positions: np.ndarray, cfg: dict,
                      seed: int, progress=None) -> dict:
    """``reaching.<graph>.*`` of ``evaluate``: the Hausdorff metric and every embedding."""
    from scipy.spatial.distance import pdist, squareform

    from sensorispace_ros.core.reach import reaching_evaluation

    reaching = cfg["representation"]["reaching"]
    options = {"n_pairs": reaching["pairs"], "max_degree": reaching["max_degree"],
               "radius": reaching["radius"]}
    # One stream for every representation: all are tested on the same pairs.
    reaching_seed = random_state(seed, "reaching")
    graphs = {"hausdorff": representation.distance}
    for dim in representation.before:
        for stage in STAGES:
            graphs[f"{dim}.{stage}"] = squareform(pdist(representation.embedding(dim, stage)))
    metrics = {}
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
    from scipy.stats import spearmanr

    return float(spearmanr(a, b).statistic)


# ---------------------------------------------------------------------------
# The one evaluation path of a run


def evaluate_output(produced: StrategyOutput, representation: Representation, cfg: dict,
                    out_dir: str | Path, strategy: str, timings: dict, progress=None,
                    started: float | None = None) -> dict:
    """Evaluate a run and write its directory; returns the metrics (nested).

    ``produced.metrics`` (dotted counters of the run) and the numbers of
    ``evaluate`` become metrics.json; ``produced.arrays`` and ``run_arrays``
    arrays.npz and the figures. ``timings`` go under ``timings_s`` with
    ``reaching`` and ``topology``, and ``total`` since ``started`` (a
    ``time.perf_counter`` value) when given.
    """
    flat = {**body_truth(cfg), **produced.metrics, **_space_numbers(representation, strategy)}
    evaluated = evaluate(representation, produced.true_positions, produced.povs, cfg,
                         cfg["seed"], progress)
    timings = {**timings, "reaching": evaluated.pop("timings_s.reaching"),
               "topology": evaluated.pop("timings_s.topology")}
    flat.update(evaluated)
    if started is not None:
        timings["total"] = time.perf_counter() - started
    arrays = {**produced.arrays, **run_arrays(produced, representation, cfg, cfg["seed"])}
    return write_run(out_dir, flat, arrays, cfg, strategy, timings, progress)


def _space_numbers(representation: Representation, strategy: str) -> dict:
    """The dimension of space the agent finds in its own metric: the estimate
    and its rounding (``naive.space_dim`` too for the naive agent)."""
    estimate = representation.space_dimension()
    found = int(round(estimate)) if np.isfinite(estimate) else -1
    numbers = {"representation.space_dim_estimate": estimate,
               "representation.space_dim": found}
    if strategy == "naive":
        numbers["naive.space_dim"] = found
    return numbers


def evaluate_graph_run(arrays, cfg: dict, results_dir: str | Path, metrics: dict | None = None,
                       strategy: str = "naive", progress=None) -> dict:
    """metrics.json, arrays.npz and figures of a representation built elsewhere
    (the ROS representation node, a bag): ``evaluate_output``, as ``reproduce``.

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
    flat.setdefault("pov.max_pose_drift", pose_drift(povs, truth["true_poses"],
                                                     Arm.from_config(cfg["arm"])))
    produced = StrategyOutput(povs=povs, pairs=arrays["pairs"], set_ids=arrays["set_ids"],
                              true_positions=arrays["true_positions"], metrics=flat,
                              arrays=arrays, timings_s={})
    return evaluate_output(produced, representation, cfg, results_dir, strategy, timings,
                           progress)


def evaluate_run(cfg: dict, results_dir: Path, bag_dir: Path | None) -> dict:
    """metrics.json + figures of a finished graph run: from the bag if one was
    recorded, otherwise from what the representation node wrote."""
    if bag_dir is not None and (bag_dir / "metadata.yaml").is_file():
        from sensorispace_ros.recording import analyze    # only a graph run reads a bag
        return analyze.analyze_bag(bag_dir, results_dir, cfg)
    return evaluate_representation(results_dir, cfg)


def evaluate_representation(results_dir: Path, cfg: dict) -> dict:
    """Evaluate what the representation node wrote (no bag needed).

    Ground truth is the body's: the sensor pose of every POV through the
    arm's forward model (``evaluate_graph_run``). The agent's own totals
    (from /agent/done) are reported under ``agent.*``.
    """
    from sensorispace_ros.graph.nodes.agent import AGENT_RECORDS_FILE
    from sensorispace_ros.graph.nodes.representation import RESULT_FILE

    with np.load(Path(results_dir) / RESULT_FILE) as stored:
        arrays = {key: stored[key] for key in stored.files}
    totals = {key[len("agent_"):]: int(value) for key, value in arrays.items()
              if key.startswith("agent_")}
    counters = {f"agent.{key}": value for key, value in totals.items()}
    # The agent's own counters under the offline strategy's names.
    for total, key in (("compensated", "exploration.compensated"),
                       ("queries", "naive.queries_total"), ("calls", "naive.calls_total")):
        if total in totals:
            counters[key] = totals[total]
    if "changes" in totals:
        counters["exploration.events"] = totals["changes"] - 1
    timings = json.loads(str(arrays.pop("timings_s_json", "{}")))
    counters.update({f"timings_s.{key}": value for key, value in timings.items()})
    arrays = {key: value for key, value in arrays.items() if not key.startswith("agent_")}
    records_file = Path(results_dir) / AGENT_RECORDS_FILE
    if records_file.is_file() and "changes" in totals:
        counters.update(_evaluate_agent_records(records_file, arrays, cfg, totals["changes"]))
    else:
        counters["analysis.naive_records"] = (f"absent (no {AGENT_RECORDS_FILE}): "
                                              "naive.* not evaluated")
    return evaluate_graph_run(arrays, cfg, results_dir, metrics=counters, strategy="naive")


def _evaluate_agent_records(records_file: Path, arrays: dict, cfg: dict, changes: int) -> dict:
    """``naive.*`` of a run without a bag, as ``analyze`` computes them from one:
    the agent's records (its own file) joined with ground truth from the seeded
    schedule (the environment plays exactly that schedule) and the body's
    forward model. Sets ``arrays["grid_index"]``."""
    with np.load(records_file) as stored:
        records = NaiveAgentRecords.from_arrays({key: stored[key] for key in stored.files})
    if not np.array_equal(records.povs, arrays["povs"]):
        return {"analysis.naive_records": f"{records_file} does not hold the representation's "
                                          "points of view: naive.* not evaluated"}
    poses = np.asarray(Arm.from_config(cfg["arm"]).forward(records.povs[:, 0]),
                       dtype=float).reshape(-1, 3)
    evaluated = naive_metrics(records, cfg, changes, poses)
    arrays["grid_index"] = evaluated.grid_index
    return {**evaluated.metrics,
            "analysis.naive_records": f"evaluated by offline.evaluation from "
                                      f"{records_file.name} (no bag); events from "
                                      "the seeded schedule"}


# ---------------------------------------------------------------------------
# A naive run's products against ground truth


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


def naive_metrics(records: NaiveAgentRecords, cfg: dict, changes: int, poses: np.ndarray,
                  recorded: dict | None = None) -> NaiveEvaluation:
    """``evaluate_naive_records`` of a graph run: ``changes`` is ``/agent/done``'s
    (``end/<k>`` closes a run of k - 1 changes), ``recorded`` the changes a bag
    holds (``ground_truth.naive_truth_of_changes``)."""
    truth = naive_truth_of_changes(cfg, int(changes) - 1, poses, recorded)
    evaluated = evaluate_naive_records(records, truth)
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
    worst, wrong = 0.0, 0
    if n_comp:
        target = truth.arm.forward(records.compensation_anchor_motor_state)
        target[:, :2] += truth.centers[events] - truth.centers[anchors]
        error = arm.pose_error(truth.arm.forward(records.compensation_motor_state), target)
        worst = float(np.max(error))
        wrong = int(np.sum(error > WRONG_POSE_TOL))
    return {
        "naive.wrong_poses": wrong,
        "naive.worst_pose_error": worst,
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

    paper_positions = truth.paper_positions
    distinct, covered, orientation_error = 0, 0, 0.0
    if len(true_poses):
        pairs_close = cKDTree(true_poses[:, :2]).query_pairs(WRONG_POSE_TOL, output_type="ndarray")
        duplicate = np.zeros(len(true_poses), dtype=bool)
        duplicate[pairs_close.max(axis=1) if len(pairs_close) else []] = True
        distinct = int(np.sum(~duplicate))
        if len(paper_positions):
            distance, _ = cKDTree(true_poses[:, :2]).query(paper_positions, k=1)
            covered = int(np.sum(distance <= WRONG_POSE_TOL))
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
