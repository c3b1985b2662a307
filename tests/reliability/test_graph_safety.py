"""A killed node must not take others with it: the launcher's
short-lease Fast DDS profile, and GraphNode publishers that retry instead of
raising when a dead reader filled a KEEP_ALL history."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

import pytest

from sensorispace_ros.graph import dds_environment, launcher

from shared import SMOKE
from .node_processes import stop_by_pid

SUBSCRIBER = """
import rclpy
from std_msgs.msg import UInt64
rclpy.init()
node = rclpy.create_node("lease_subscriber")
node.create_subscription(UInt64, "/lease_probe", lambda m: None, 10)
rclpy.spin(node)
"""


def test_graph_environment_names_a_default_participant_profile_with_a_short_lease(tmp_path):
    env = dds_environment.graph_environment(5, base={"PATH": "/usr/bin"}, profile_dir=tmp_path)
    root = ET.parse(env["FASTRTPS_DEFAULT_PROFILES_FILE"]).getroot()
    ns = {"d": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    participant = root.find("d:profiles/d:participant", ns)
    assert participant.get("is_default_profile") == "true"
    lease = participant.find("d:rtps/d:builtin/d:discovery_config/d:leaseDuration/d:sec", ns)
    assert int(lease.text) == dds_environment.LEASE_DURATION_S < 20


def test_graph_environment_keeps_a_profile_the_user_set(tmp_path):
    env = dds_environment.graph_environment(5, base={"FASTRTPS_DEFAULT_PROFILES_FILE": "/mine.xml"},
                                            profile_dir=tmp_path)
    assert env["FASTRTPS_DEFAULT_PROFILES_FILE"] == "/mine.xml"


@pytest.mark.graph
@pytest.mark.timeout(60)
def test_a_killed_reader_is_unmatched_within_the_short_lease(domain_id, tmp_path):
    """Measured without the profile: 19.9 s (Fast DDS's 20 s default lease)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions
    from std_msgs.msg import UInt64

    env = dds_environment.graph_environment(domain_id, profile_dir=tmp_path)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    subscriber = subprocess.Popen([sys.executable, "-c", SUBSCRIBER], env=env,
                                  start_new_session=True)
    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = rclpy.create_node("lease_publisher", context=context)
        publisher = node.create_publisher(UInt64, "/lease_probe", 10)
        deadline = time.monotonic() + 30
        while publisher.get_subscription_count() == 0:
            assert time.monotonic() < deadline, "the subscriber never matched"
            time.sleep(0.05)
        os.kill(subscriber.pid, 9)
        subscriber.wait()
        killed = time.monotonic()
        while publisher.get_subscription_count() > 0 and time.monotonic() - killed < 15:
            time.sleep(0.05)
        unmatched_after = time.monotonic() - killed
        assert unmatched_after < dds_environment.LEASE_DURATION_S + 2.0, unmatched_after
    finally:
        stop_by_pid(subscriber)
        context.try_shutdown()


@pytest.fixture
def graph_node(domain_id):
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    from sensorispace_ros.graph.framework import GraphNode

    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    node = GraphNode("publish_retry_probe", context=context)
    yield node
    node.destroy_node()
    context.try_shutdown()


def failing_publish(monkeypatch, failures: int):
    """Publisher.publish raising rclpy's "cannot publish data" ``failures`` times."""
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    from rclpy.publisher import Publisher

    sent = []

    def publish(self, msg):
        if len(sent) < failures:
            sent.append(None)
            raise _rclpy.RCLError("Failed to publish: cannot publish data")
        sent.append(msg)
    monkeypatch.setattr(Publisher, "publish", publish)
    return sent


def test_a_publish_that_fails_for_a_while_is_retried_until_it_goes_through(graph_node,
                                                                           monkeypatch):
    from std_msgs.msg import UInt64

    sent = failing_publish(monkeypatch, failures=3)
    publisher = graph_node.create_publisher(UInt64, "/retry_probe", 10)
    assert publisher.publish(UInt64(data=7)) is True
    assert sent[-1].data == 7 and len(sent) == 4
    assert graph_node.publish_failures == 3


def test_a_publish_that_keeps_failing_is_given_up_without_raising(graph_node, monkeypatch):
    from std_msgs.msg import UInt64

    from sensorispace_ros.graph import framework as nodes

    failing_publish(monkeypatch, failures=10**9)
    monkeypatch.setattr(nodes, "PUBLISH_RETRY_S", 0.3)
    publisher = graph_node.create_publisher(UInt64, "/retry_probe", 10)
    started = time.monotonic()
    assert publisher.publish(UInt64(data=7)) is False
    assert 0.3 <= time.monotonic() - started < 3.0


def test_another_publish_error_is_logged_and_given_up_at_once(graph_node, monkeypatch):
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    from rclpy.publisher import Publisher
    from std_msgs.msg import UInt64

    def publish(self, msg):
        raise _rclpy.RCLError("Failed to publish: some other failure")
    monkeypatch.setattr(Publisher, "publish", publish)
    publisher = graph_node.create_publisher(UInt64, "/retry_probe", 10)
    started = time.monotonic()
    assert publisher.publish(UInt64(data=7)) is False
    assert time.monotonic() - started < 0.5 and graph_node.publish_failures == 1


def test_launch_refuses_a_negative_respawn_count(capsys):
    from sensorispace_ros.cli import main as cli

    assert cli.main(["launch", "--config", str(SMOKE), "--respawn", "-1"]) == 2
    assert "--respawn must be >= 0, got -1" in capsys.readouterr().err
    with pytest.raises(ValueError, match="respawn must be >= 0"):
        launcher.launch_graph(SMOKE, respawn=-1)


# Exits with RESTART_EXIT_CODE the first time (leaving a marker), then runs the node.
_ASK_ONCE = ("import os, sys\n"
             "marker, code, command = sys.argv[1], int(sys.argv[2]), sys.argv[3:]\n"
             "if not os.path.exists(marker):\n"
             "    open(marker, 'w').close()\n"
             "    sys.exit(code)\n"
             "os.execv(command[0], command)\n")


@pytest.mark.graph
@pytest.mark.timeout(240)
def test_launch_starts_again_a_node_that_asks_for_it(tmp_path, monkeypatch, domain_id):
    import io

    from sensorispace_ros.graph.framework import RESTART_EXIT_CODE
    real_command = launcher.node_command
    marker = tmp_path / "body.asked"

    def node_command(name, config_path, parameters):
        command = real_command(name, config_path, parameters)
        if name != "body":
            return command
        return [sys.executable, "-c", _ASK_ONCE, str(marker), str(RESTART_EXIT_CODE), *command]

    monkeypatch.setattr(launcher, "node_command", node_command)
    log = io.StringIO()
    result = launcher.launch_graph(SMOKE, run="asked", domain_id=domain_id, record=False,
                                   results_root=tmp_path / "results", timeout_s=200,
                                   stream=log)
    assert marker.is_file()
    assert "body asked to be restarted (exit code 75); started again (1/3" in log.getvalue()
    assert result.exit_code == 0, log.getvalue()
    assert (result.results_dir / "logs" / "body.restart-1.log").is_file()
    assert json.loads((result.results_dir / "metrics.json").read_text())["pov"]["count"] > 3
