"""The agent node on the row clock survives a kill -9 (docs/clock.md, the graph).

``config/smoke.yaml`` with ``world.clock: rows`` (and ``wall``): the body, the environment
and the representation run in this process (the body's ground truth of rows
is read from it), the agent as a process of its own with
``graph.checkpoint_dir``. Once the agent has written a snapshot it gets
SIGKILL by its PID and is started again with the same command line. The
restarted agent must go on from the snapshot (its POVs and reactions, not a
fresh start), number its commands after the dead agent's, and the run must end
by itself with metrics a graph run has: POVs found after the restart, nothing
non-finite, nothing accepted across a change, the restart and the rows it lost
counted. The world kept its clock while the agent was dead: the run is not the
uninterrupted one bit for bit. Started once more on the run over, the agent
publishes its results again and ends. A snapshot that is not a clocked run, or is one
of another body, stops the agent naming ``graph.checkpoint_dir``.
"""
import re
import time

import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.graph import in_process, launcher
from sensorispace_ros.graph.dds_environment import graph_environment
from sensorispace_ros.protocol import SNAPSHOT_FILE
from sensorispace_ros.state.agent_journal import read_snapshot

from shared import SMOKE, SMOKE_ROW_CLOCK, SMOKE_WALL_CLOCK, NodeProcess, spin_graph, stop_by_pid

pytestmark = [pytest.mark.graph]

# The shared row-clock world on the smoke config's own 16 x 16 grid: the kill below is
# timed against that world's run.
ROWS = {**SMOKE_ROW_CLOCK, "world.grid_count": 16}
# The dead agent works on this long after its first snapshot holding a POV (its rows are lost).
KILL_AFTER_SNAPSHOT_S = 0.5
TIMEOUT_S = 400.0


@pytest.mark.slow
@pytest.mark.parametrize("overrides", [ROWS, SMOKE_WALL_CLOCK], ids=["rows", "wall"])
def test_the_agent_killed_on_its_own_clock_resumes_from_its_snapshot(overrides, tmp_path,
                                                                     domain_id, monkeypatch):
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    from sensorispace_ros.core.run_world import run_world
    from sensorispace_ros.evaluation.clock import clock_metrics
    from sensorispace_ros.evaluation.graph_clock import graph_clocked_run
    from sensorispace_ros.evaluation.naive import evaluate_naive_run
    from sensorispace_ros.graph.nodes.body import BodyNode
    from sensorispace_ros.core.world_clock import clock_events
    from sensorispace_ros.graph.nodes.environment import EnvironmentNode
    from sensorispace_ros.graph.nodes.agent_restart import CLOCK_STATE_FILE
    from sensorispace_ros.graph.nodes.representation import RepresentationNode
    from sensorispace_ros.state.resting_state import RestingStateFile

    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.delenv("ROS_STATIC_PEERS", raising=False)
    cfg = config.load_config(SMOKE, overrides=overrides)
    path = tmp_path / "clock.yaml"
    path.write_text(config.to_parameter_file(cfg))
    world = run_world(cfg)
    results, checkpoints = tmp_path / "results", tmp_path / "checkpoints"
    snapshot_path = checkpoints / SNAPSHOT_FILE
    env = graph_environment(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_STATIC_PEERS", None)
    agent = NodeProcess("agent", launcher.node_command("agent", path, {
        "graph.results_dir": str(results), "graph.checkpoint_dir": str(checkpoints),
        "graph.exit_when_done": True}), env, tmp_path)

    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    overrides = in_process.parameter_overrides(path, {"graph.results_dir": str(results),
                                                      "graph.resend_period_s": 0.5,
                                                      "graph.exit_when_done": False})
    graph = in_process._InProcessGraph(context, overrides, {
        "representation": RepresentationNode, "body": BodyNode,
        "environment": EnvironmentNode})
    killed = snapshot_seen = None
    try:
        for name in graph.factories:
            graph.make(name)
        agent.start()
        started = time.monotonic()
        representation = graph.nodes["representation"]
        while representation.result is None:
            assert time.monotonic() - started < TIMEOUT_S, f"no end; logs {agent.logs}"
            spin_graph(graph, 0.1)
            if snapshot_seen is None and _holds_a_pov(snapshot_path):
                snapshot_seen = time.monotonic()
            if killed is None and snapshot_seen is not None \
                    and time.monotonic() - snapshot_seen > KILL_AFTER_SNAPSHOT_S:
                agent.kill9()
                killed = read_snapshot(snapshot_path)
                sent = RestingStateFile(checkpoints / CLOCK_STATE_FILE, 3).load()
                agent.start()
            elif agent.process.poll() not in (None, 0):
                raise AssertionError(f"the agent died: {agent.process.returncode}; {agent.logs}")
        agent.process.wait(timeout=30)
        body = graph.nodes["body"]
        wall_s = time.monotonic() - started
        assert agent.process.returncode == 0
        # Started once more on the run over: it publishes its results again, and ends.
        agent.start()
        while agent.process.poll() is None:
            assert time.monotonic() - started < TIMEOUT_S, f"no end; logs {agent.logs}"
            spin_graph(graph, 0.1)
    finally:
        stop_by_pid(agent.process)
        graph.close()
        context.try_shutdown()
    assert agent.process.returncode == 0

    # Killed mid-run, after some work: the snapshot is of a run not over.
    assert killed is not None and not killed["over"], "the run ended before the kill"
    at_kill = killed["run"]
    kill_povs, kill_reactions = len(at_kill.agent.points_of_view), len(at_kill.event_states) - 1
    assert kill_reactions > 0 and kill_povs > 0
    # The restarted agent went on from that snapshot: its first words say so.
    said = agent.logs[1].read_text()
    resumed = re.search(r"resuming on the clock \(restart 1\): snapshot of (\d+) reactions "
                        r"kept, (\d+) POVs; commands from (\d+)", said)
    assert resumed is not None, said[-2000:]
    assert (int(resumed[1]), int(resumed[2])) == (kill_reactions, kill_povs)
    # ... and numbered its commands after every one the dead agent sent.
    requests_at_kill, rows_at_kill, restarts_at_kill = (int(x) for x in sent)
    assert restarts_at_kill == 0 and requests_at_kill >= killed["requests"]
    assert int(resumed[3]) == requests_at_kill + 1

    final = read_snapshot(snapshot_path)
    assert final["over"]
    run = final["run"]
    again = agent.logs[2].read_text()
    assert "resuming on the clock (restart 2): snapshot of " \
        f"{len(run.event_states) - 1} reactions kept, {len(run.agent.points_of_view)} POVs, " \
        "the run over" in again, again[-2000:]
    assert f"run over: found {len(run.agent.points_of_view)} points of view" in again
    # What the dead agent sent after its snapshot is counted as lost.
    assert run.restarts == 1
    assert run.rows_lost_to_restart == rows_at_kill - at_kill.body.rows_sent >= 0
    povs = run.agent.points_of_view
    np.testing.assert_array_equal(povs[:kill_povs], at_kill.agent.points_of_view)
    # It went on reacting; on the row clock it finds more (on the wall clock what it finds
    # after the kill depends on the machine's load: the world does not wait for it).
    assert len(run.event_states) - 1 > kill_reactions
    assert len(povs) > kill_povs or cfg["world"]["clock"] == "wall"
    # The representation has what the restarted agent published.
    np.testing.assert_array_equal(representation.result["povs"], povs)

    if cfg["world"]["clock"] == "rows":
        # The body executed those rows (and held some) between the snapshot and
        # the kill (when the last command noted reached it before the kill).
        if requests_at_kill in body.rows_after:
            assert run.rows_lost_to_restart <= \
                body.rows_after[requests_at_kill] - body.rows_after[killed["requests"]]
        truth = {"clocked_body": body.clocked_body, "rows_after": body.rows_after}
    else:
        truth = {"state_after": body.state_after}
    evaluated = graph_clocked_run(run, world, clock_events(world, cfg), **truth)
    metrics = dict(evaluate_naive_run(evaluated, world).metrics)
    metrics.update(clock_metrics(evaluated, world))
    assert np.isfinite(evaluated.povs).all()
    assert all(np.isfinite(v) for v in metrics.values() if isinstance(v, (int, float)))
    assert metrics["naive.accepted_across_change"] == 0
    assert metrics["naive.clock.restarts"] == 1
    assert metrics["pov.count"] == len(povs)
    print({"wall_s": round(wall_s, 1), "killed_at_reactions": kill_reactions,
           "povs_at_kill": kill_povs, **{k: metrics[k] for k in (
               "pov.count", "naive.coverage", "naive.clock.reactions",
               "naive.clock.rows_lost_to_restart", "naive.clock.restarts",
               "naive.accepted_across_change", "naive.clock.recall")
        if k in metrics}})


def _holds_a_pov(snapshot_path) -> bool:
    """Whether the agent's snapshot (written atomically) holds a POV: it is
    killed after some work, however long its first POV takes on this machine."""
    snapshot = read_snapshot(snapshot_path)
    return snapshot is not None and len(snapshot["run"].agent.points_of_view) > 0


def _clocked_agent(context, tmp_path, checkpoints):
    from sensorispace_ros.graph.nodes.agent import AgentNode

    path = tmp_path / "clock.yaml"
    path.write_text(config.to_parameter_file(config.load_config(SMOKE, overrides=ROWS)))
    return AgentNode(context=context, parameter_overrides=in_process.parameter_overrides(
        path, {"graph.results_dir": str(tmp_path), "graph.checkpoint_dir": str(checkpoints)}))


def test_a_snapshot_without_a_clocked_run_stops_the_agent_at_start_up(context, tmp_path):
    from sensorispace_ros.state.agent_journal import write_snapshot

    checkpoints = tmp_path / "checkpoints"
    first = _clocked_agent(context, tmp_path, checkpoints)       # nothing there: a fresh start
    cfg = first.cfg
    first.destroy_node()
    write_snapshot(checkpoints / SNAPSHOT_FILE, {"config": cfg, "agent": {}})   # lockstep's
    with pytest.raises(config.ConfigError,
                       match=r"graph\.checkpoint_dir: .*agent\.snapshot: no clocked run"):
        _clocked_agent(context, tmp_path, checkpoints)


def test_a_clocked_snapshot_of_another_body_stops_the_agent_naming_the_file(context, tmp_path):
    from sensorispace_ros import messages
    from sensorispace_ros.core.body_description import BodyDescription
    from sensorispace_ros.core.clocked_run import ClockedRun
    from sensorispace_ros.graph.clocked_exploration import ClockOverTopics
    from sensorispace_ros.state.agent_journal import write_snapshot

    checkpoints = tmp_path / "checkpoints"
    first = _clocked_agent(context, tmp_path, checkpoints)
    cfg = first.cfg
    first.destroy_node()

    class Other:
        n_motors, n_sensors = 4, 7
        description = BodyDescription.revolute(4, 7)
    write_snapshot(checkpoints / SNAPSHOT_FILE, {
        "config": cfg, "description": Other.description, "requests": 5, "over": False,
        "run": ClockedRun(None, ClockOverTopics(Other()))})
    second = _clocked_agent(context, tmp_path, checkpoints)
    try:
        errors = []
        second.get_logger().error = errors.append
        second.on_description(messages.description_to_msg(BodyDescription.revolute(4, 6)))
        assert second.finished and second.exit_code == 2
        assert len(errors) == 1 and "graph.checkpoint_dir" in errors[0] \
            and "agent.snapshot: unusable clocked run" in errors[0]
    finally:
        second.destroy_node()


def test_the_body_says_simulation_2_again_before_each_hold_answer(context, tmp_path):
    # A restarted agent may have missed the first equality/<k>: it hears it at its next hold.
    from types import SimpleNamespace

    from sensorispace_ros.graph.nodes.body import BodyNode

    path = tmp_path / "clock.yaml"
    path.write_text(config.to_parameter_file(config.load_config(SMOKE, overrides=ROWS)))
    node = BodyNode(context=context, parameter_overrides=in_process.parameter_overrides(
        path, {"graph.results_dir": str(tmp_path)}))
    try:
        said = []
        node.sensation_packer = SimpleNamespace(pack=lambda rows, frame_id, stamp: frame_id)
        node.sensation_pub = SimpleNamespace(publish=said.append)
        motor, sensed = np.zeros((1, node.description.n_motors)), \
            np.zeros((1, node.description.receptors))
        node.clock_answer(sensed, motor, "cmd/1")
        assert said == ["cmd/1"]                     # simulation 1: nothing said
        node.n_events = -1                           # the world now replays its schedule
        for frame_id in ("cmd/2", "cmd/3", "hold/4", "cmd/5", "hold/6"):
            node.clock_answer(sensed, motor, frame_id)
        assert said[1:] == ["equality/0", "cmd/2", "cmd/3", "equality/0", "hold/4", "cmd/5",
                            "equality/0", "hold/6"]
    finally:
        node.destroy_node()
