"""The one evaluation path of a run: ``evaluate_output``.

The offline run (``reproduce``), a graph run (``evaluate_graph_run``: from
a bag through ``analyze``, or from what the representation node wrote through
``graph_run``) and the sweep's runs all end here: the ground truth of the run
(``ground_truth.RunTruth``, built once and handed down), the numbers of
``evaluator.evaluate``, and the run directory (``write_run``).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from sensorispace_ros import config as config_mod
from sensorispace_ros.core.arm import Arm
from sensorispace_ros.evaluation.evaluator import evaluate
from sensorispace_ros.evaluation.ground_truth import RunTruth, body_truth, ground_truth_from_motor
from sensorispace_ros.evaluation.run_files import (ARRAYS_FILE, FIGURES_DIR, METRICS_FILE, nest,
                                                   representation_from_arrays, run_arrays,
                                                   write_metrics)
from sensorispace_ros.offline.pov_assembly import MIN_POVS
from sensorispace_ros.offline.representation import Representation
from sensorispace_ros.offline.strategies import StrategyOutput, pose_drift
from sensorispace_ros.offline.timing import timed_stage


def evaluate_output(produced: StrategyOutput, representation: Representation, cfg: dict,
                    out_dir: str | Path, strategy: str, timings: dict, progress=None,
                    started: float | None = None, truth: RunTruth | None = None) -> dict:
    """Evaluate a run and write its directory; returns the metrics (nested).

    ``produced.metrics`` (dotted counters of the run) and the numbers of
    ``evaluate`` become metrics.json; ``produced.arrays`` and ``run_arrays``
    arrays.npz and the figures. ``timings`` go under ``timings_s`` with
    ``reaching`` and ``topology``, and ``total`` since ``started`` (a
    ``time.perf_counter`` value) when given. ``truth``: the run's ground
    truth when the caller built it (else from ``produced.world``, or built here).
    """
    if truth is None:
        truth = RunTruth(cfg, produced.world)
    flat = {**body_truth(truth.world), **produced.metrics,
            **_space_numbers(representation, strategy)}
    angle, turning = None, cfg["world"]["rotation_count"] >= 2 and "true_poses" in produced.arrays
    if turning:
        from sensorispace_ros.evaluation.rotations import rotation_numbers
        from sensorispace_ros.evaluation.pose_reaching import pose_reaching_numbers

        turning_numbers, angle = rotation_numbers(
            representation.distance,
            {f"{dim}.{stage}": representation.embedding(dim, stage)
             for dim in representation.before for stage in ("before", "after")},
            produced.arrays["true_poses"], produced.pairs, produced.set_ids,
            flat["representation.space_dim"], strategy, cfg, cfg["seed"])
        flat.update(turning_numbers)
        flat.update(pose_reaching_numbers(representation, produced.arrays["true_poses"], cfg,
                                          cfg["seed"], angle))
    evaluated = evaluate(representation, produced.true_positions, produced.povs, cfg,
                         cfg["seed"], progress)
    timings = {**timings, "reaching": evaluated.pop("timings_s.reaching"),
               "topology": evaluated.pop("timings_s.topology")}
    flat.update(evaluated)
    if started is not None:
        timings["total"] = time.perf_counter() - started
    arrays = {**produced.arrays, **run_arrays(produced, representation, cfg, cfg["seed"])}
    metrics = write_run(out_dir, flat, arrays, cfg, strategy, timings, progress)
    if turning and cfg["output"]["figures"]:
        from sensorispace_ros.evaluation import rotations

        rotations.draw_orientation_figure(arrays, angle,
                                          Path(out_dir) / FIGURES_DIR / rotations.FIGURE_NAME)
    return metrics


def write_without_representation(produced: StrategyOutput, cfg: dict, out_dir: str | Path,
                                 strategy: str, truth: RunTruth, started: float | None) -> dict:
    """The run directory of a run that found too few POVs for a representation:
    metrics.json with what it found and ``outcome``, a one-line account of why
    there is no representation (no figures)."""
    flat = {**body_truth(truth.world), **produced.metrics}
    flat["outcome"] = outcome_line(flat, len(produced.povs))
    arrays = {**produced.arrays, "povs": np.asarray(produced.povs),
              "pairs": np.asarray(produced.pairs).reshape(-1, 2),
              "set_ids": np.asarray(produced.set_ids)}
    timings = dict(produced.timings_s)
    if started is not None:
        timings["total"] = time.perf_counter() - started
    return write_run(out_dir, flat, arrays, {**cfg, "output": {**cfg["output"], "figures": False}},
                     strategy, timings)


def outcome_line(flat: dict, n_povs: int) -> str:
    """What the agent found, in one line, when it is too little for a representation."""
    found = [f"{n_povs} points of view (a representation needs at least {MIN_POVS})"]
    for key, name in (("naive.pose_rank", "pose rank"), ("naive.pov_dim", "POV dimension"),
                      ("naive.noise_estimate", "sensory noise"),
                      ("exploration.compensated", "compensations")):
        if key in flat:
            found.append(f"{name} {flat[key]:.3g}" if isinstance(flat[key], float)
                         else f"{name} {flat[key]}")
    return "no representation: the agent found " + ", ".join(found)


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
                       strategy: str = "naive", progress=None,
                       truth: RunTruth | None = None) -> dict:
    """metrics.json, arrays.npz and figures of a representation built elsewhere
    (the ROS representation node, a bag): ``evaluate_output``, as ``reproduce``.

    ``arrays`` holds the ``run_arrays`` names (``povs``, ``pairs``,
    ``set_ids``, ``hausdorff``, ``embedding_*``, ``set_spread_*``);
    ``true_positions`` and the exploration arrays are taken from it when
    present, else computed from the forward model. ``metrics``: dotted
    counters known to the caller (``exploration.*``, ``naive.*``, timings as
    ``timings_s.*``). ``truth``: the run's ground truth when the caller
    built it (``analyze``), else built here. Ground truth from the forward
    model fills the arrays the caller did not give. Fewer POVs than a
    representation needs: the run directory without one
    (``write_without_representation``).
    """
    started = time.perf_counter()
    cfg = config_mod.validate_config(cfg)
    arrays = {key: np.asarray(value) for key, value in dict(arrays).items()}
    flat = {key: value for key, value in (metrics or {}).items()
            if not key.startswith("timings_s.")}
    timings = {key[len("timings_s."):]: value for key, value in (metrics or {}).items()
               if key.startswith("timings_s.")}
    povs = arrays["povs"]
    if len(povs) < MIN_POVS:        # the representation node built none (its "reason")
        produced = StrategyOutput(povs=povs, pairs=arrays["pairs"], set_ids=arrays["set_ids"],
                                  true_positions=None, metrics={"pov.count": int(len(povs)), **flat},
                                  arrays={}, timings_s=timings)
        return write_without_representation(produced, cfg, results_dir, strategy,
                                            truth if truth is not None else RunTruth(cfg),
                                            started)
    representation = representation_from_arrays(arrays)
    from_motor = ground_truth_from_motor(povs, cfg)
    for key, value in from_motor.items():
        arrays.setdefault(key, value)
    for key, value in representation.timings_s.items():
        timings.setdefault(key, value)
    flat.setdefault("pov.count", int(len(povs)))
    flat.setdefault("pov.max_pose_drift", pose_drift(povs, from_motor["true_poses"],
                                                     Arm.from_config(cfg["arm"])))
    produced = StrategyOutput(povs=povs, pairs=arrays["pairs"], set_ids=arrays["set_ids"],
                              true_positions=arrays["true_positions"], metrics=flat,
                              arrays=arrays, timings_s={})
    return evaluate_output(produced, representation, cfg, results_dir, strategy, timings,
                           progress, truth=truth)


def write_run(out_dir: str | Path, flat_metrics: dict, arrays: dict, cfg: dict, strategy: str,
              timings: dict, progress=None) -> dict:
    """Figures (when ``cfg["output"]["figures"]``), arrays.npz and metrics.json
    of a finished run; returns the metrics.

    ``flat_metrics`` has dotted keys; ``timings`` go under ``timings_s``
    (figure drawing is timed as ``figures``, outside ``total``).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    timings = dict(timings)
    arrays = dict(arrays)
    if cfg["output"]["figures"]:
        from sensorispace_ros.evaluation import figures   # matplotlib loads only to draw

        with timed_stage(progress, "figures", timings, total=len(figures.FIGURES)):
            arrays.update(figures.draw_run_figures(arrays, cfg, out_dir / FIGURES_DIR, progress))
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
