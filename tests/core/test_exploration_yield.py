"""When exploring stops paying (core/naive/exploration_yield.py) and a
clocked run that stops exploring before its schedule runs out."""
import pytest

from sensorispace_ros import config
from sensorispace_ros.core.clocked_run import run_on_clock
from sensorispace_ros.core.naive.exploration_yield import ExplorationYield
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.run_world import run_world
from sensorispace_ros.evaluation.clock import clock_metrics
from sensorispace_ros.evaluation.naive import evaluate_naive_run


def _steady(rule: ExplorationYield, povs: int, cost: int) -> None:
    for k in range(1, povs + 1):
        assert not rule.explored(k * cost, k)


def test_a_steady_cost_per_pov_never_stops():
    _steady(ExplorationYield(ratio=1.5, window=4), 200, 100)


def test_a_drought_stops_exactly_where_the_window_costs_ratio_times_the_mean():
    # 20 POVs at 100 motor states each: the POV 4 before the last was known at
    # 1,600. With Q probed and no new POV, (Q - 1600) / 4 > 2 * Q / 20 from Q > 2666.7.
    rule = ExplorationYield(ratio=2.0, window=4)
    _steady(rule, 20, 100)
    assert not rule.explored(2666, 20)
    assert rule.explored(2667, 20) and rule.stopped_at == 2667
    # It stays stopped, whatever comes next.
    assert rule.explored(2700, 25) and rule.stopped_at == 2667


def test_not_before_twice_the_window():
    rule = ExplorationYield(ratio=1.0, window=8)
    _steady(rule, 15, 10)
    assert not rule.explored(10**9, 15)
    assert rule.explored(10**9, 16)


def test_ratio_zero_never_stops():
    rule = ExplorationYield(ratio=0.0, window=1)
    _steady(rule, 10, 1)
    assert not rule.explored(10**12, 10)


@pytest.mark.parametrize("ratio, window, name", [(-1.0, 4, "ratio"), (float("nan"), 4, "ratio"),
                                                 (2.0, 0, "window")])
def test_bad_settings_are_refused(ratio, window, name):
    with pytest.raises(ValueError, match=name):
        ExplorationYield(ratio=ratio, window=window)


@pytest.mark.parametrize("name, value", [("clock_stop_ratio", -0.5), ("clock_stop_window", 0)])
def test_its_parameters_are_checked_at_start_up(name, value):
    with pytest.raises(config.ConfigError, match=rf"naive\.{name}"):
        config.load_config("config/smoke.yaml", {f"naive.{name}": value})


def _smoke_on_the_clock(**naive):
    cfg = config.load_config("config/smoke.yaml", {
        "world.clock": "rows", "world.change_interval": 1000.0,
        **{f"naive.{k}": v for k, v in naive.items()}})
    world = run_world(cfg)
    run = run_on_clock(world, NaiveParams(**cfg["naive"]), "rows", interval=1000.0)
    return world, run, {**evaluate_naive_run(run, world).metrics, **clock_metrics(run, world)}


def test_an_agent_that_stops_exploring_turns_to_simulation_2_before_the_schedule_ends():
    _, run, metrics = _smoke_on_the_clock(clock_stop_ratio=1.5, clock_stop_window=2)
    _, _, whole = _smoke_on_the_clock()
    stopped = metrics["naive.clock.explored_at"]
    assert 0 < stopped < whole["naive.queries_total"]
    assert whole["naive.clock.explored_at"] == 0
    # Simulation 2 came before the schedule's second round, and the run ended with it.
    assert metrics["naive.clock.rows"] < whole["naive.clock.rows"]
    assert metrics["naive.clock.reactions"] < whole["naive.clock.reactions"]
    pairs, set_ids = run.agent.equality_sets()
    assert len(set_ids) and len(pairs) > len(set_ids) // 2
    assert metrics["naive.queries_total"] < whole["naive.queries_total"]
    assert metrics["naive.accepted_across_change"] == 0 and metrics["naive.wrong_poses"] == 0
