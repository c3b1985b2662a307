"""Security defaults: discovery stays on localhost unless configured, and a
graph on another ROS_DOMAIN_ID sees nothing of this one."""
from __future__ import annotations

import os
import time

import pytest

from sensorispace_ros.graph.dds_environment import free_domain_id as probe_domain_id
from sensorispace_ros.graph.dds_environment import graph_environment

from shared import free_domain_id

pytestmark = [pytest.mark.graph]

PROBE_TOPIC = f"/reliability/isolation_probe_{os.getpid()}"
# Published on the home domain only and subscribed nowhere: it may show up in a
# topic list only through discovery of the home domain's participants.
HOME_ONLY_TOPIC = f"/reliability/home_only_{os.getpid()}"


def _participant(domain: int, name: str):
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    context = Context()
    rclpy.init(context=context, domain_id=domain,
               signal_handler_options=SignalHandlerOptions.NO)
    return context, rclpy.create_node(name, context=context)


def test_a_graph_on_another_domain_sees_nothing():
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    home = free_domain_id()
    # A second free id, not the first one (the probe only tests ports, so
    # two calls may return the same id until a participant binds it).
    other = probe_domain_id(home % 100 + 1)
    assert other != home
    home_ctx, talker = _participant(home, "isolation_talker")
    same_ctx, same_listener = _participant(home, "isolation_same_domain")
    other_ctx, other_listener = _participant(other, "isolation_other_domain")
    received = {"same": 0, "other": 0}
    publisher = talker.create_publisher(String, PROBE_TOPIC, 10)
    talker.create_publisher(String, HOME_ONLY_TOPIC, 10)
    same_listener.create_subscription(
        String, PROBE_TOPIC, lambda _: received.__setitem__("same", received["same"] + 1), 10)
    other_listener.create_subscription(
        String, PROBE_TOPIC, lambda _: received.__setitem__("other", received["other"] + 1), 10)
    executors = []
    for ctx, node in ((home_ctx, talker), (same_ctx, same_listener), (other_ctx, other_listener)):
        executor = SingleThreadedExecutor(context=ctx)
        executor.add_node(node)
        executors.append(executor)
    try:
        deadline = time.monotonic() + 6.0
        while time.monotonic() < deadline:
            publisher.publish(String(data="secret"))
            for executor in executors:
                executor.spin_once(timeout_sec=0.02)
            if received["same"] >= 5 and time.monotonic() > deadline - 3.0:
                break
        other_nodes = set(other_listener.get_node_names())
        other_topics = {name for name, _ in other_listener.get_topic_names_and_types()}
        home_topics = {name for name, _ in same_listener.get_topic_names_and_types()}
        other_publishers = other_listener.count_publishers(PROBE_TOPIC)
        other_publisher_info = other_listener.get_publishers_info_by_topic(PROBE_TOPIC)
    finally:
        for executor in executors:
            executor.shutdown()
        for ctx, node in ((home_ctx, talker), (same_ctx, same_listener),
                          (other_ctx, other_listener)):
            node.destroy_node()
            ctx.try_shutdown()
    # Positive control: the same domain does see the talker and its messages.
    assert received["same"] >= 5 and HOME_ONLY_TOPIC in home_topics
    assert received["other"] == 0
    assert other_publishers == 0 and not other_publisher_info
    assert HOME_ONLY_TOPIC not in other_topics
    assert not {"isolation_talker", "isolation_same_domain"} & other_nodes


def test_launcher_children_discover_on_localhost_only_by_default():
    env = graph_environment(42, base={"PATH": "/usr/bin"})
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert env["ROS_DOMAIN_ID"] == "42"
    assert "ROS_STATIC_PEERS" not in env


def test_launcher_keeps_a_discovery_range_the_user_chose():
    env = graph_environment(7, base={"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET",
                                     "ROS_DOMAIN_ID": "0"})
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET"
    assert env["ROS_DOMAIN_ID"] == "7"     # the launcher's domain always wins
