"""The evaluator's judgement of a naive run: a compensation is wrong when its
pose is more than a quarter of a grid step from the pose its anchor asks for,
two POVs are one position when closer than that, pose precision and motor
states per POV are reported, and a run that finds too few POVs for a
representation still writes its metrics with a one-line account."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from shared import SMOKE
from sensorispace_ros import config
from sensorispace_ros.core.naive.records import NaiveAgentRecords
from sensorispace_ros.core.run_world import run_world
from sensorispace_ros.evaluation.ground_truth import naive_truth_of_run
from sensorispace_ros.evaluation.naive import evaluate_naive_records
from sensorispace_ros.evaluation.reproduce import reproduce


@pytest.fixture(scope="module")
def judged(smoke_naive_run):
    world = run_world(config.load_config(SMOKE))
    records = NaiveAgentRecords.from_agent(smoke_naive_run.agent)
    truth = naive_truth_of_run(smoke_naive_run, world, paper_positions=np.zeros((0, 2)))
    return records, truth


def _moved_target(truth, event: int, by: float):
    """``truth`` with the object at ``event`` moved by ``by`` along x: the pose
    every compensation of that event is asked for moves as much."""
    centers = truth.centers.copy()
    centers[event, 0] += by
    return dataclasses.replace(truth, centers=centers)


def test_a_pose_a_quarter_step_off_is_wrong_and_a_fifth_is_not(judged):
    records, truth = judged
    assert truth.pose_tolerance == pytest.approx(truth.spacing / 4)
    honest = evaluate_naive_records(records, truth).metrics
    assert honest["naive.wrong_poses"] == 0
    event = int(records.compensation_event[0])
    n_at_event = int(np.sum(records.compensation_event == event))
    off = evaluate_naive_records(records, _moved_target(truth, event, 0.3 * truth.spacing))
    near = evaluate_naive_records(records, _moved_target(truth, event, 0.2 * truth.spacing))
    assert off.metrics["naive.wrong_poses"] == n_at_event
    assert near.metrics["naive.wrong_poses"] == 0
    assert near.metrics["naive.worst_pose_error"] == pytest.approx(0.2 * truth.spacing, rel=1e-3)


def test_pose_precision_and_motor_states_per_pov_are_reported(judged):
    records, truth = judged
    m = evaluate_naive_records(records, truth).metrics
    assert 0 <= m["naive.pose_error_median"] <= m["naive.pose_error_p95"] <= m["naive.worst_pose_error"]
    assert m["naive.pose_error_p95"] < 1e-6                  # a noiseless body's compensations
    assert m["naive.queries_total_per_pov"] == pytest.approx(
        records.queries_total / len(records.povs))
    assert m["naive.queries_total_per_pov"] > m["naive.queries_per_pov"]


def test_a_run_with_too_few_points_of_view_writes_its_metrics_and_says_why(tmp_path):
    # Two links whose eye turns with both joints: it cannot keep its direction
    # while following a translation, so the agent finds its start's POV only.
    cfg = config.load_config(SMOKE, {"arm.segments": [1.5, 1.5], "arm.eye": "link",
                                     "arm.initial_motor_state": [0.0, 0.0],
                                     "world.retina.receptors": 3})
    metrics = reproduce(cfg, "naive", out_dir=tmp_path, figures=False)
    written = json.loads((tmp_path / "metrics.json").read_text())
    assert written["pov"]["count"] < 4
    assert written["outcome"].startswith(
        f"no representation: the agent found {written['pov']['count']} points of view")
    assert "pose rank 2" in written["outcome"]
    assert written["outcome"] == metrics["outcome"]
    assert "quality" not in written and (tmp_path / "arrays.npz").is_file()


def test_every_naive_position_is_a_paper_position(smoke_naive_reference):
    """Anchors recorded at the start and after changes give one lattice of
    sensor positions, the paper strategy's: the object starts on its grid."""
    metrics = smoke_naive_reference.metrics
    assert metrics["naive.distinct_positions"] >= 4
    assert metrics["naive.coverage_of_paper_positions"] == metrics["naive.coverage"]
