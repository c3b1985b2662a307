"""The body node on the row clock survives a kill -9 (docs/clock.md, the graph).

With ``graph.checkpoint_dir`` the body writes after each command or hold it
executes where the clock and the arm stood before and after it
(``body.clock``). A body started again on that file answers the command the
agent sends again (its answer may not have got out) as the dead body did, bit
for bit, and the commands after it as an uninterrupted body would: the row
clock is the rows executed, so the restart changes nothing the agent sees. An
older command is dropped. Checked on an imperfect body (noise numbered by
command, joints landing off) whose world changes inside the commands, and
end to end: the body process killed mid-run and started again, the agent's
POVs, equality sets and motor states are the offline run's, and so is the
body's record of time (``body.truth.log`` read back by the restarted body).
"""
import os
import re
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest

from sensorispace_ros import config, messages
from sensorispace_ros.graph import in_process, launcher
from sensorispace_ros.graph.dds_environment import graph_environment
from sensorispace_ros.messages.clouds import FloatCloud
from sensorispace_ros.state.clock_truth import read_clock_truth

from shared import SMOKE, SMOKE_ROW_CLOCK, NodeProcess, spin_graph, stop_by_pid

pytestmark = [pytest.mark.graph]

# A change every 15 rows on average: most commands of 40 rows have one inside.
IMPERFECT = {"world.clock": "rows", "world.change_interval": 15.0,
             "world.retina.noise": 1e-3, "arm.motor_noise": 1e-4}


def _body(context, tmp_path, checkpoints=None, overrides=IMPERFECT):
    from sensorispace_ros.graph.nodes.body import BodyNode

    tmp_path.mkdir(parents=True, exist_ok=True)
    path = tmp_path / "clock.yaml"
    path.write_text(config.to_parameter_file(config.load_config(SMOKE, overrides=overrides)))
    extra = {"graph.results_dir": str(tmp_path)}
    if checkpoints is not None:
        extra["graph.checkpoint_dir"] = str(checkpoints)
    node = BodyNode(context=context, parameter_overrides=in_process.parameter_overrides(
        path, extra))
    node.said = []
    node.sensation_packer = SimpleNamespace(
        pack=lambda rows, frame_id, stamp: (frame_id, np.array(rows, copy=True)))
    node.sensation_pub = SimpleNamespace(publish=node.said.append)
    node.pose_pub = node.joint_pub = SimpleNamespace(publish=lambda data: None)
    return node


def _commands(n_motors: int):
    rng = np.random.default_rng(5)
    start = np.array([0.1, -1.5, 2.2, -3.0])[:n_motors]
    return [start + rng.normal(0.0, 0.3, size=(40, n_motors)) for _ in range(6)]


def _send(node, number: int, rows: np.ndarray, band=None) -> None:
    if band is not None:                          # a hold at the command's first row
        packer = messages.CloudCdrPacker(node.columns_of("/body/hold"))
        return node.on_hold(packer.pack(np.concatenate([rows[0], *band])[None],
                                        f"hold/{number}", 0))
    node.clock_command("cmd", number, FloatCloud(f"cmd/{number}", 0, rows))


def _answers(node) -> dict:
    return {frame_id: rows for frame_id, rows in node.said}


def test_a_restarted_body_answers_as_the_uninterrupted_one(context, tmp_path):
    commands = _commands(4)
    # Command 3 holds still at command 2's last row while it senses as then.
    commands[2] = commands[1][-1:]
    reference = _body(context, tmp_path / "a")
    try:
        _send(reference, 1, commands[0])
        _send(reference, 2, commands[1])
        band = (reference.said[-1][1][-1] - 0.01, reference.said[-1][1][-1] + 0.01)

        def send(node, number):
            _send(node, number, commands[number - 1], band if number == 3 else None)
        for number in range(3, len(commands) + 1):
            send(reference, number)
        uninterrupted = _answers(reference)
        rows_after, row = reference.rows_after, reference.clocked_body.row
        change_row = reference.clocked_body.change_row
        truth = (dict(rows_after), dict(reference.state_after),
                 reference.clocked_body.rest_jumps.copy())
    finally:
        reference.destroy_node()
    assert list(uninterrupted) == [f"{'hold' if n == 3 else 'cmd'}/{n}"
                                   for n in range(1, len(commands) + 1)]
    # The hold lasted, and the world changed inside commands.
    assert rows_after[3] - rows_after[2] > 1
    inside = [n for n in range(1, len(commands) + 1) if n != 3 and np.any(
        (change_row > rows_after[n - 1]) & (change_row < rows_after[n]))]
    assert len(inside) >= 2
    # Killed after command n: the agent sends n again (no answer got out) or n + 1.
    for killed_after, sent_again in [(n, n + k) for n in range(2, 7) for k in (0, 1)
                                     if n + k <= len(commands)]:
        checkpoints = tmp_path / f"checkpoints-{killed_after}-{sent_again}"
        dead = _body(context, tmp_path / "b", checkpoints)
        try:
            for number in range(1, killed_after + 1):
                send(dead, number)
        finally:
            dead.destroy_node()
        if sent_again == killed_after:
            # Killed while it logged the command it had executed: half a record written.
            log = checkpoints / "body.truth.log"
            os.truncate(log, log.stat().st_size - 12)
        restarted = _body(context, tmp_path / "c", checkpoints)
        try:
            # A command answered before the restart is dropped.
            send(restarted, 1)
            assert not restarted.said and restarted.dropped["/body/motor_command"] == 1
            for number in range(sent_again, len(commands) + 1):
                send(restarted, number)
            again = _answers(restarted)
            assert list(again) == list(uninterrupted)[sent_again - 1:]
            for frame_id, rows in again.items():
                np.testing.assert_array_equal(rows, uninterrupted[frame_id], err_msg=frame_id)
            assert restarted.clocked_body.row == row
            # What the dead body knew of time is known again: the evaluator's record is whole.
            assert restarted.truth_whole
            assert (restarted.rows_after, restarted.state_after) == truth[:2]
            np.testing.assert_array_equal(restarted.clocked_body.rest_jumps, truth[2])
        finally:
            restarted.destroy_node()


def test_a_body_without_a_checkpoint_starts_its_clock_at_row_zero(context, tmp_path):
    checkpoints = tmp_path / "checkpoints"
    first = _body(context, tmp_path, checkpoints)
    try:
        _send(first, 1, _commands(4)[0])
        assert first.clocked_body.row == 40
    finally:
        first.destroy_node()
    fresh = _body(context, tmp_path)              # no graph.checkpoint_dir: nothing read
    again = _body(context, tmp_path, checkpoints)
    try:
        assert fresh.clocked_body.row == 0 and again.clocked_body.row == 40
    finally:
        fresh.destroy_node()
        again.destroy_node()


KILL_AT_COMMAND = 300
TIMEOUT_S = 400.0


@pytest.mark.slow
def test_the_body_killed_on_the_row_clock_changes_nothing_the_agent_finds(
        tmp_path, domain_id, monkeypatch):
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    from sensorispace_ros.core.clocked_run import run_on_clock
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.run_world import run_world
    from sensorispace_ros.graph.nodes.agent import AgentNode
    from sensorispace_ros.graph.nodes.environment import EnvironmentNode
    from sensorispace_ros.graph.nodes.representation import RepresentationNode

    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.delenv("ROS_STATIC_PEERS", raising=False)
    cfg = config.load_config(SMOKE, overrides=SMOKE_ROW_CLOCK)
    path = tmp_path / "clock.yaml"
    path.write_text(config.to_parameter_file(cfg))
    offline = run_on_clock(run_world(cfg), NaiveParams(**cfg["naive"]), "rows",
                           interval=cfg["world"]["change_interval"])
    env = graph_environment(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_STATIC_PEERS", None)
    body = NodeProcess("body", launcher.node_command("body", path, {
        "graph.results_dir": str(tmp_path / "results"),
        "graph.checkpoint_dir": str(tmp_path / "checkpoints"), "graph.exit_when_done": True}),
        env, tmp_path)

    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    overrides = in_process.parameter_overrides(path, {
        "graph.results_dir": str(tmp_path / "results"), "graph.command_timeout_s": 0.5,
        "graph.exit_when_done": False})
    graph = in_process._InProcessGraph(context, overrides, {
        "representation": RepresentationNode, "agent": AgentNode,
        "environment": EnvironmentNode})
    killed_at = []

    def kill_and_restart(agent):
        # The agent's driver runs inside the spin (its ``step``): watched from a thread.
        while not killed_at and representation.result is None:
            sent = agent.body.requests if agent.body is not None else 0
            if sent >= KILL_AT_COMMAND:
                body.kill9()
                killed_at.append(sent)
                body.start()
            time.sleep(0.001)
    try:
        for name in graph.factories:
            graph.make(name)
        body.start()
        agent, representation = graph.nodes["agent"], graph.nodes["representation"]
        watcher = threading.Thread(target=kill_and_restart, args=(agent,), daemon=True)
        watcher.start()
        started = time.monotonic()
        while representation.result is None:
            assert time.monotonic() - started < TIMEOUT_S, f"no end; logs {body.logs}"
            spin_graph(graph, 0.1)
        watcher.join(timeout=10)
        retransmits = agent.body.retransmits
        run = agent.clock_run
    finally:
        stop_by_pid(body.process)
        graph.close()
        context.try_shutdown()
    assert killed_at, "the run ended before the kill"
    killed_at = killed_at[0]
    said = body.logs[1].read_text()
    resumed = re.search(r"restarted on the row clock: resumed after command (\d+) at row (\d+)",
                        said)
    assert resumed is not None, said[-2000:]
    assert int(resumed[1]) in (killed_at - 1, killed_at) and int(resumed[2]) > 0
    assert retransmits >= 1            # the command (or hold) the dead body left unanswered
    # The restart changed nothing the agent did or found.
    assert (run.agent.queries_total, run.agent.calls_total) == (
        offline.agent.queries_total, offline.agent.calls_total)
    np.testing.assert_array_equal(run.agent.points_of_view, offline.povs)
    np.testing.assert_array_equal(representation.result["povs"], offline.povs)
    np.testing.assert_array_equal(representation.result["pairs"], offline.pairs)
    # The body's record of time, the dead body's part read back from its log, is the
    # offline run's: the launched run is evaluated as an uninterrupted one.
    truth = read_clock_truth(tmp_path / "checkpoints" / "body.truth.npz")
    assert truth["whole"] and len(truth["rows_after"]) > killed_at
    assert (truth["rows"], truth["held_rows"]) == (offline.clock.rows, offline.clock.held_rows)
    np.testing.assert_array_equal(truth["rest_jumps"], offline.clock.rest_jumps)
    print({"killed_at_command": killed_at, "resumed_after": int(resumed[1]),
           "row": int(resumed[2]), "retransmits": retransmits,
           "povs": len(offline.povs)})
