"""What the nodes persist for a restart (issue #7): the body's resting-state
file, and the environment's progress file (an in-process environment node
with a probe node on a private context)."""
from __future__ import annotations

import json
import time

import numpy as np
import pytest

from sensorispace_ros.nodes.body import RestingStateFile
from sensorispace_ros.nodes.environment import PROGRESS_BYTES


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

    def __init__(self, domain_id: int, checkpoint_dir):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from sensorispace_ros import contracts, launcher
        from sensorispace_ros.nodes.environment import EnvironmentNode

        from .conftest import SMOKE
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.env = EnvironmentNode(context=self.context, parameter_overrides=launcher.
                                   parameter_overrides(SMOKE, {
                                       "graph.checkpoint_dir": str(checkpoint_dir),
                                       "graph.wait_for_nodes": ["environment_probe"],
                                       "graph.resend_period_s": 0.05}))
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
