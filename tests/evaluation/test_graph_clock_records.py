"""A launched run on its own clock is evaluated only from a whole record
(``evaluation.graph_clock.clocked_numbers``): a missing file or a body that
restarted without its log gives no ``naive.*`` number and says why."""
from sensorispace_ros import config
from sensorispace_ros.evaluation.graph_clock import clocked_numbers
from sensorispace_ros.state.agent_journal import write_snapshot
from sensorispace_ros.state.clock_truth import write_clock_truth

from shared import SMOKE


def test_a_run_without_a_whole_record_of_time_says_why_it_is_not_evaluated(tmp_path):
    cfg = config.load_config(SMOKE, overrides={"world.clock": "rows"})
    missing = clocked_numbers(cfg, tmp_path)
    assert list(missing) == ["analysis.naive_records"]
    assert "no body.truth.npz or no agent.snapshot" in missing["analysis.naive_records"]
    write_snapshot(tmp_path / "agent.snapshot", {"over": True, "run": None})
    write_clock_truth(tmp_path / "body.truth.npz", {0: 0, 1: 40}, {1: 0}, whole=False)
    restarted = clocked_numbers(cfg, tmp_path)
    assert list(restarted) == ["analysis.naive_records"]
    assert "restarted without its body.truth.log" in restarted["analysis.naive_records"]
