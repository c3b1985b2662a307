"""The naive agent in a world on its own clock (world.clock: rows): it is
told nothing, detects the changes from its sensory flow, drops what a change
cut through and accepts nothing that spans two world states."""
import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.clocked_run import run_on_clock
from sensorispace_ros.core.run_world import run_world
from sensorispace_ros.evaluation.clock import clock_metrics
from sensorispace_ros.evaluation.naive import evaluate_naive_run

SMOKE = "config/smoke.yaml"


@pytest.fixture(scope="module")
def clocked_smoke():
    cfg = config.load_config(SMOKE, {"world.clock": "rows", "world.change_interval": 1000.0})
    world = run_world(cfg)
    run = run_on_clock(world, NaiveParams(**cfg["naive"]), "rows", interval=1000.0)
    metrics = {**evaluate_naive_run(run, world).metrics, **clock_metrics(run, world)}
    return world, run, metrics


def test_no_react_per_change_and_no_notice(clocked_smoke):
    world, run, metrics = clocked_smoke
    truth = run.clock
    # Changes came faster than the agent finished its work: it reacted to
    # fewer than there were (the schedule, then simulation 2 through it
    # again) and some of its reactions were cut.
    assert metrics["naive.clock.changes"] == 2 * len(world.events)
    assert metrics["naive.clock.reactions"] < metrics["naive.clock.changes"]
    assert truth.undone > 0 and truth.lost_rows > 0
    assert truth.held_rows > 0 and truth.rows > truth.held_rows


def test_nothing_accepted_spans_two_worlds(clocked_smoke):
    _, run, metrics = clocked_smoke
    assert metrics["naive.accepted_across_change"] == 0
    assert metrics["naive.wrong_poses"] == 0
    assert metrics["naive.state_changes_accepted"] == 0
    assert metrics["naive.accepted_across_redistribution"] == 0
    assert run.agent.compensated > 0


def test_changes_are_detected_from_the_flow(clocked_smoke):
    _, _, metrics = clocked_smoke
    assert metrics["naive.clock.detectable"] > 50
    assert metrics["naive.clock.recall"] >= 0.99
    assert metrics["naive.clock.false_detection_rate"] <= 0.01


def test_simulation_2_on_the_clock_gives_equality_sets(clocked_smoke):
    _, run, _ = clocked_smoke
    pairs, set_ids = run.agent.equality_sets()
    assert run.agent.queries_by_stage.get("equality_pass", 0) > 0
    assert len(np.unique(set_ids)) > 50 and len(pairs) > 2 * len(np.unique(set_ids))


def test_the_same_seed_gives_the_same_run(clocked_smoke):
    world, run, _ = clocked_smoke
    cfg = config.load_config(SMOKE)
    again = run_on_clock(world, NaiveParams(**cfg["naive"]), "rows", interval=1000.0)
    assert np.array_equal(again.povs, run.povs)
    assert again.agent.queries_total == run.agent.queries_total


def test_wall_clock_is_refused_offline():
    cfg = config.load_config(SMOKE, {"world.clock": "wall"})
    with pytest.raises(config.ConfigError, match=r"world\.clock"):
        run_on_clock(run_world(cfg), NaiveParams(**cfg["naive"]), "wall", interval=1000.0)
