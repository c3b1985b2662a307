"""What the nodes persist for a restart: the body's resting-state
file, and the environment's progress file (an in-process environment node
with a probe node on a private context)."""
from __future__ import annotations

import json
import time

import numpy as np
import pytest

from sensorispace_ros.state.resting_state import RestingStateFile
from sensorispace_ros.state.environment_record import PROGRESS_BYTES


def test_resting_state_file_returns_the_last_state_saved_after_a_reopen(tmp_path):
    path = tmp_path / "body.state"
    assert RestingStateFile(path, 4).load() is None          # fresh file: nothing to resume
    written = RestingStateFile(path, 4)
    for k in range(5):
        written.save(np.array([k, -1.5, 2.2, -3.0]))
    reopened = RestingStateFile(path, 4)                      # a restarted body
    np.testing.assert_array_equal(reopened.load(), [4, -1.5, 2.2, -3.0])
    reopened.save(np.array([9.0, 9.0, 9.0, 9.0]))             # numbering goes on
    np.testing.assert_array_equal(RestingStateFile(path, 4).load(), [9.0, 9.0, 9.0, 9.0])


def test_resting_state_file_ignores_a_slot_torn_by_a_kill_mid_write(tmp_path):
    path = tmp_path / "body.state"
    state = RestingStateFile(path, 4)
    state.save(np.array([1.0, 1.0, 1.0, 1.0]))
    state.save(np.array([2.0, 2.0, 2.0, 2.0]))
    # a kill after the first sequence number and half the row of the next save
    torn = state.slots[(state.seq + 1) % 2]
    torn[0] = state.seq + 1
    torn[1:3] = 7.0
    np.testing.assert_array_equal(RestingStateFile(path, 4).load(), [2.0, 2.0, 2.0, 2.0])


def test_resting_state_file_of_another_size_is_started_afresh(tmp_path):
    path = tmp_path / "body.state"
    path.write_bytes(b"\x01" * 13)
    assert RestingStateFile(path, 4).load() is None


class EnvironmentProbe:
    """An EnvironmentNode (smoke config, private context) with a listener on its
    lights and events and a publisher of /agent/settled."""

    def __init__(self, domain_id: int, checkpoint_dir, resend_period_s: float = 0.05):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from sensorispace_ros import contracts
        from sensorispace_ros.graph import in_process
        from sensorispace_ros.graph.nodes.environment import EnvironmentNode

        from shared import SMOKE
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.env = EnvironmentNode(context=self.context, parameter_overrides=in_process.
                                   parameter_overrides(SMOKE, {
                                       "graph.checkpoint_dir": str(checkpoint_dir),
                                       "graph.wait_for_nodes": ["environment_probe"],
                                       "graph.resend_period_s": resend_period_s}))
        self.probe = rclpy.create_node("environment_probe", context=self.context)
        self.lights, self.events = [], []
        contracts.create_subscription(self.probe, "/environment/lights",
                                      lambda m: self.lights.append(m.header.frame_id))
        contracts.create_subscription(self.probe, "/environment/event",
                                      lambda m: self.events.append(m.header.frame_id))
        self.settle_pub = contracts.create_publisher(self.probe, "/agent/settled")
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.env)
        self.executor.add_node(self.probe)

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.02)

    def settle(self, k: int) -> None:
        from std_msgs.msg import UInt64
        self.settle_pub.publish(UInt64(data=k))

    def close(self) -> None:
        self.executor.shutdown()
        self.env.close()
        self.env.destroy_node()
        self.probe.destroy_node()
        self.context.try_shutdown()


@pytest.mark.graph
@pytest.mark.timeout(60)
def test_the_environment_starts_when_its_peers_are_there_not_at_its_next_resend(
        tmp_path, domain_id):
    # The start polls the graph every PEER_POLL_S; the resend timer (30 s here)
    # only repeats what was sent.
    probe = EnvironmentProbe(domain_id, tmp_path, resend_period_s=30.0)
    try:
        probe.spin(3.0)
        assert probe.lights[:1] == ["change/0"] and probe.events == [], probe.lights
    finally:
        probe.close()


@pytest.mark.graph
@pytest.mark.timeout(60)
def test_a_restarted_environment_resumes_at_its_current_change_and_resends_it_until_settled(
        tmp_path, domain_id):
    (tmp_path / "environment.json").write_text(json.dumps({"current": 5, "settled": 4}))
    probe = EnvironmentProbe(domain_id, tmp_path)
    try:
        probe.spin(2.0)
        # not rewound to change 0; change 5 (event + lights) again, its lights re-sent
        assert probe.events == ["change/5"], probe.events
        assert probe.lights.count("change/5") >= 5 and set(probe.lights) == {"change/5"}
        probe.settle(5)
        probe.spin(1.0)
        assert probe.events == ["change/5", "change/6"]
        assert probe.lights[-1] == "change/6"
        before = len(probe.lights)
        probe.spin(0.5)       # change 6 is a normal change: sent once, not re-sent
        assert len(probe.lights) == before
        assert json.loads((tmp_path / "environment.json").read_text()) == \
            {"current": 6, "settled": 5}
        assert (tmp_path / "environment.json").stat().st_size == PROGRESS_BYTES  # in place
    finally:
        probe.close()


@pytest.mark.graph
@pytest.mark.timeout(60)
def test_an_environment_killed_between_a_settle_and_the_next_change_goes_on(tmp_path,
                                                                           domain_id):
    (tmp_path / "environment.json").write_text(json.dumps({"current": 5, "settled": 5}))
    probe = EnvironmentProbe(domain_id, tmp_path)
    try:
        probe.spin(1.5)
        assert probe.events == ["change/6"] and set(probe.lights) == {"change/6"}
    finally:
        probe.close()


@pytest.mark.graph
@pytest.mark.timeout(60)
def test_an_environment_with_an_unusable_progress_file_starts_afresh(tmp_path, domain_id):
    (tmp_path / "environment.json").write_text(json.dumps({"current": 10**6, "settled": 0}))
    probe = EnvironmentProbe(domain_id, tmp_path)
    try:
        probe.spin(1.0)
        assert probe.events == [] and probe.lights and set(probe.lights) == {"change/0"}
    finally:
        probe.close()


@pytest.mark.graph
@pytest.mark.timeout(60)
def test_a_repeated_settle_of_the_previous_change_gets_the_current_lights_again(tmp_path,
                                                                               domain_id):
    """A restarted agent that lost the passive sensation of the current change
    re-sends its last settle; the environment answers with the current lights."""
    (tmp_path / "environment.json").write_text(json.dumps({"current": 5, "settled": 5}))
    probe = EnvironmentProbe(domain_id, tmp_path)
    try:
        probe.spin(1.0)
        assert probe.lights == ["change/6"] and probe.events == ["change/6"]
        probe.settle(5)
        probe.spin(0.5)
        assert probe.lights == ["change/6", "change/6"] and probe.events == ["change/6"]
        assert probe.env.current == 6 and probe.env.settled == 5
        assert "/agent/settled" not in probe.env.dropped
    finally:
        probe.close()


@pytest.mark.graph
@pytest.mark.timeout(60)
def test_a_restarted_body_answers_commands_only_once_the_lights_of_before_the_kill_are_back(
        tmp_path, domain_id, capfd):
    """The lights history (transient_local) reaches a restarted body interleaved with the
    agent's re-sent command; answering it in an old change's lights made the agent diverge
    (seen once in ~12 body restarts). The body persists the number of the lights it last
    applied and holds commands until that change is back."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from sensorispace_ros import contracts, messages
    from sensorispace_ros.graph import in_process
    from sensorispace_ros.core.body import SimulatedBody
    from sensorispace_ros.graph.framework import RESTART_EXIT_CODE, build_world, frame
    from sensorispace_ros.graph.nodes.body import BodyNode

    from shared import SMOKE
    cfg_overrides = in_process.parameter_overrides(SMOKE, {"graph.checkpoint_dir": str(tmp_path)})
    resting = np.array([0.3, -1.2, 2.0, -2.5])
    RestingStateFile(tmp_path / "body.state", 5).save(np.append(resting, 3))  # lights 3 applied

    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    body = BodyNode(context=context, parameter_overrides=cfg_overrides)
    probe = rclpy.create_node("body_probe", context=context)
    executor = SingleThreadedExecutor(context=context)
    try:
        executor.add_node(body)
        executor.add_node(probe)
        world = build_world(body.cfg)
        old_lights = np.asarray(world.initial_lights)
        current_lights = old_lights + np.array([0.7, -0.4])
        answers = {}
        sensation_columns = contracts.contract("/body/sensation").columns_for(body.description)
        contracts.create_subscription(
            probe, "/body/sensation",
            lambda m: answers.setdefault(m.header.frame_id, []).append(
                messages.cloud_to_matrix(m, sensation_columns)))
        lights_pub = contracts.create_publisher(probe, "/environment/lights")
        command_pub = contracts.create_publisher(probe, "/body/motor_command")
        lights_columns = contracts.contract("/environment/lights").columns
        command_columns = contracts.contract("/body/motor_command").columns_for(body.description)
        motor = np.array([[0.1, -1.5, 2.2, -3.0], [0.2, -1.4, 2.1, -2.9]])

        def spin(seconds):
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                executor.spin_once(timeout_sec=0.02)

        def send_lights(k, lights):
            lights_pub.publish(messages.matrix_to_cloud(
                lights, lights_columns, messages.make_header(frame("change", k), 0)))

        def send_command():
            command_pub.publish(messages.matrix_to_cloud(
                motor, command_columns, messages.make_header(frame("cmd", 7), 0)))

        spin(1.0)                               # discovery
        assert np.array_equal(body.body.motor_state, resting)   # restored resting state
        send_lights(1, old_lights)              # the history, oldest first ...
        spin(0.3)
        send_command()                          # ... interleaved with the re-sent command
        spin(0.5)
        assert "cmd/7" not in answers           # held: change 3 is not back yet
        send_lights(3, current_lights)
        spin(0.3)
        send_command()                          # the agent's next re-send
        spin(0.5)
        assert len(answers.get("cmd/7", [])) == 1
        expected = SimulatedBody(world.receptors, current_lights, world.m0.copy()).sense(motor)
        assert np.array_equal(answers["cmd/7"][0], expected)
        wrong = SimulatedBody(world.receptors, old_lights, world.m0.copy()).sense(motor)
        assert not np.allclose(answers["cmd/7"][0], wrong)
        # Held copies are not answers: asked for once so far. Two more re-sends of
        # an answered command mean two answers were lost: the body says so.
        assert body.command_asked == ("cmd/7", 1)
        send_command()
        spin(0.3)
        assert "asked for a third time" not in capfd.readouterr().err
        send_command()
        spin(0.5)
        assert len(answers["cmd/7"]) == 3 and body.command_asked == ("cmd/7", 3)
        assert "cmd/7 asked for a third time" in capfd.readouterr().err
        # It has a checkpoint: it stops (after answering) to be started again.
        assert body.finished and body.exit_code == RESTART_EXIT_CODE
    finally:
        executor.shutdown()
        body.destroy_node()
        probe.destroy_node()
        context.try_shutdown()
