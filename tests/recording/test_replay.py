"""The replay node: everything republished, byte-exact and in order; timing honoured."""
from __future__ import annotations

from rosbags.typesys import Stores, get_typestore

from sensorispace_ros.recording.bag_format import (
    SESSION_CONFIG_TOPIC,
    SESSION_CONFIG_TYPE,
    session_config_cdr,
)
from sensorispace_ros.recording.bag_writer import BagWriter

from bag_test_support import wait_for

STORE = get_typestore(Stores.ROS2_JAZZY)
SETTLED, SENSATION = "/agent/settled", "/body/sensation"


def uint64_cdr(n: int) -> bytes:
    return bytes(STORE.serialize_cdr(STORE.types["std_msgs/msg/UInt64"](data=n),
                                     "std_msgs/msg/UInt64"))


def cloud_cdr(n: int) -> bytes:
    types = STORE.types
    cloud = types["sensor_msgs/msg/PointCloud2"](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=0, nanosec=n), frame_id=str(n)),
        height=1, width=0, fields=[], is_bigendian=False, point_step=0, row_step=0,
        data=__import__("numpy").zeros(0, "uint8"), is_dense=True)
    return bytes(STORE.serialize_cdr(cloud, "sensor_msgs/msg/PointCloud2"))


def on_the_wire(cdr: bytes) -> bytes:
    """DDS pads a serialized payload to a multiple of 4 bytes (zeros; CDR readers,
    rosbags included, accept that padding)."""
    return cdr + b"\0" * (-len(cdr) % 4)


def make_bag(path, n, spacing_ns):
    with BagWriter(path, {SETTLED: "std_msgs/msg/UInt64",
                          SENSATION: "sensor_msgs/msg/PointCloud2",
                          SESSION_CONFIG_TOPIC: SESSION_CONFIG_TYPE}) as writer:
        writer.write(SESSION_CONFIG_TOPIC, 0, session_config_cdr("seed: 1\n"))
        for i in range(n):
            writer.write(SETTLED, 1_000 + i * spacing_ns, uint64_cdr(i))
            writer.write(SENSATION, 1_001 + i * spacing_ns, cloud_cdr(i))


class RawListener:
    def __init__(self, context, topics):
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        from sensorispace_ros import contracts

        self.node = Node("test_listener", context=context)
        self.received = {t: [] for t in topics}
        self.sent_ns = []  # the publisher's stamps: the listener's own load cannot bend them
        for topic in topics:
            contracts.create_subscription(self.node, topic, self._keep(topic), raw=True)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)

    def _keep(self, topic):
        def keep(cdr, info):
            self.received[topic].append(cdr)
            self.sent_ns.append(info["source_timestamp"])
        return keep

    def spin(self):
        self.executor.spin_once(timeout_sec=0.05)


def replay(children, ros_env, bag, *params):
    args = ["-m", "sensorispace_ros.graph.nodes.replay", "--ros-args", "-p", f"bag_path:={bag}"]
    for param in params:
        args += ["-p", param]
    return children(args, ros_env["env"])


def test_fast_replay_republishes_every_message_exactly_and_in_order(
        ros_env, ros_context, children, tmp_path):
    n = 2000
    make_bag(tmp_path / "bag", n, spacing_ns=1_000_000)
    listener = RawListener(ros_context, [SETTLED, SENSATION])
    process = replay(children, ros_env, tmp_path / "bag", "rate:=0.0")
    wait_for(lambda: all(len(v) == n for v in listener.received.values()), 60,
             "every replayed message", spin=listener.spin)
    assert listener.received[SETTLED] == [on_the_wire(uint64_cdr(i)) for i in range(n)]
    assert listener.received[SENSATION] == [on_the_wire(cloud_cdr(i)) for i in range(n)]
    output, _ = process.communicate(timeout=30)
    assert process.returncode == 0, output
    assert f"replayed {2 * n + 1} messages" in output


def test_timed_replay_keeps_the_recorded_spacing_scaled_by_rate(
        ros_env, ros_context, children, tmp_path):
    make_bag(tmp_path / "bag", 11, spacing_ns=100_000_000)  # 1.0 s of recording
    listener = RawListener(ros_context, [SETTLED])
    process = replay(children, ros_env, tmp_path / "bag", "rate:=2.0", f"topics:=[{SETTLED}]")
    wait_for(lambda: len(listener.received[SETTLED]) == 11, 30, "11 messages", spin=listener.spin)
    elapsed = (listener.sent_ns[-1] - listener.sent_ns[0]) / 1e9
    # 1.0 s at 2x = 0.5 s; fast mode would be ~0. A replay that falls behind and catches
    # up shortens the span, hence the margin below 0.5.
    assert 0.35 <= elapsed < 2.0, elapsed
    assert all(b > a for a, b in zip(listener.sent_ns, listener.sent_ns[1:]))
    assert listener.received[SETTLED] == [on_the_wire(uint64_cdr(i)) for i in range(11)]
    process.communicate(timeout=30)
    assert process.returncode == 0


def test_publishing_waits_a_grace_after_the_subscribers_matched(ros_env, ros_context, tmp_path):
    # The replay's publisher may see a subscriber before that subscriber sees
    # the publisher; a volatile reader that matches a writer after its first
    # messages skips them. So publishing waits ``match_grace_s`` after the match.
    import time

    from rclpy.parameter import Parameter

    from sensorispace_ros.graph.nodes.replay import Replay

    make_bag(tmp_path / "bag", 3, spacing_ns=1_000_000)
    listener = RawListener(ros_context, [SETTLED])
    waited = {}
    for grace in (0.0, 0.8):
        node = Replay(bag_path=str(tmp_path / "bag"), topics=[SETTLED], context=ros_context,
                      parameter_overrides=[Parameter("match_grace_s", value=grace)])
        started = time.monotonic()
        assert node.wait_for_subscribers() == []
        waited[grace] = time.monotonic() - started
        node.destroy_node()
    assert waited[0.8] >= 0.8 and waited[0.8] - waited[0.0] >= 0.6
    listener.node.destroy_node()


def test_replay_of_a_missing_bag_is_a_one_line_error(ros_env, children, tmp_path):
    process = replay(children, ros_env, tmp_path / "nothing")
    output, _ = process.communicate(timeout=30)
    assert process.returncode == 2
    assert output.strip().splitlines() == [f"replay: bag {tmp_path / 'nothing'} does not exist"]
