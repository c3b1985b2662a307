"""A graph run evaluated without its bag: what the representation node wrote
(``protocol.RESULT_FILE``) and the agent's records (``protocol.AGENT_RECORDS_FILE``),
with the ground truth of the run's configuration; ``evaluate_run`` picks
the bag (``analyze``) when the run recorded one.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from sensorispace_ros import config as config_mod
from sensorispace_ros.core.arm import Arm
from sensorispace_ros.core.naive.records import NaiveAgentRecords
from sensorispace_ros.evaluation import analyze
from sensorispace_ros.evaluation.ground_truth import RunTruth
from sensorispace_ros.evaluation.naive import naive_metrics
from sensorispace_ros.evaluation.runs import evaluate_graph_run
from sensorispace_ros.evaluation.graph_clock import clocked_numbers
from sensorispace_ros.protocol import AGENT_RECORDS_FILE, CHECKPOINTS, RESULT_FILE


def evaluate_run(cfg: dict, results_dir: Path, bag_dir: Path | None) -> dict:
    """metrics.json + figures of a finished graph run: from the bag if one was
    recorded, otherwise from what the representation node wrote."""
    if bag_dir is not None and (bag_dir / "metadata.yaml").is_file():
        return analyze.analyze_bag(bag_dir, results_dir, cfg)
    return evaluate_representation(results_dir, cfg)


def evaluate_representation(results_dir: Path, cfg: dict) -> dict:
    """Evaluate what the representation node wrote (no bag needed).

    Ground truth is the body's: the sensor pose of every POV through the
    arm's forward model (``evaluate_graph_run``). The agent's own totals
    (from /agent/done) are reported under ``agent.*``.
    """
    cfg = config_mod.validate_config(cfg)
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
    truth = RunTruth(cfg)
    if cfg["world"]["clock"] != "agent":
        counters.update(clocked_numbers(cfg, Path(results_dir) / CHECKPOINTS))
    elif records_file.is_file() and "changes" in totals:
        counters.update(_evaluate_agent_records(records_file, arrays, truth, totals["changes"]))
    else:
        counters["analysis.naive_records"] = (f"absent (no {AGENT_RECORDS_FILE}): "
                                              "naive.* not evaluated")
    return evaluate_graph_run(arrays, cfg, results_dir, metrics=counters, strategy="naive",
                              truth=truth)


def _evaluate_agent_records(records_file: Path, arrays: dict, truth: RunTruth,
                            changes: int) -> dict:
    """``naive.*`` of a run without a bag, as ``analyze`` computes them from one:
    the agent's records (its own file) joined with ground truth from the seeded
    schedule (the environment plays exactly that schedule) and the body's
    forward model; a world that waits for the agent only (``clocked_numbers``
    otherwise). Sets ``arrays["grid_index"]``."""
    with np.load(records_file) as stored:
        records = NaiveAgentRecords.from_arrays({key: stored[key] for key in stored.files})
    found = arrays["povs"]
    if len(records.povs) != len(found) or (len(found) and not np.array_equal(records.povs,
                                                                              found)):
        return {"analysis.naive_records": f"{records_file} does not hold the representation's "
                                          "points of view: naive.* not evaluated"}
    poses = np.asarray(Arm.from_config(truth.cfg["arm"]).forward(records.povs[:, 0]),
                       dtype=float).reshape(-1, 3)
    evaluated = naive_metrics(records, truth, changes, poses)
    arrays["grid_index"] = evaluated.grid_index
    return {**evaluated.metrics,
            "analysis.naive_records": f"evaluated by evaluation.naive from "
                                      f"{records_file.name} (no bag); events from "
                                      "the seeded schedule"}
