"""GraphNode's reading of the probe topics' bytes (read_float_cloud: the same
results and drop reasons as read_serialized + decode) and its clock (now_ns:
the node clock's time, simulated time included). A node on a private context,
no graph."""
import time

import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rclpy.time import Time

from sensorispace_ros import contracts, messages
from sensorispace_ros.graph import in_process
from sensorispace_ros.graph.framework import MAX_FRAME_NUMBER, GraphNode, parse_frame

from .conftest import SMOKE

SENSATION = contracts.contract("/body/sensation").columns
KINDS = ("cmd", "change", "end")


def _node(context, **graph):
    node = GraphNode("reader", context=context,
                     parameter_overrides=in_process.parameter_overrides(SMOKE, graph))
    node.reasons = []
    node.drop = lambda topic, reason: node.reasons.append((topic, reason))
    return node


def _as_before(node, topic, msg, kinds):
    """on_sensation's reading before read_float_cloud."""
    msg = node.read_serialized(topic, msg)
    decoded = None if msg is None else node.decode(topic, msg, kinds)
    if decoded is None:
        return None
    return decoded[0], msg.header.frame_id, messages.stamp_ns(msg.header), decoded[1].tobytes()


def _read(node, topic, msg, kinds):
    read = node.read_float_cloud(topic, msg, kinds)
    if read is None:
        return None
    parsed, cloud = read
    return parsed, cloud.frame_id, cloud.stamp_ns, cloud.matrix.tobytes()


def _messages():
    packer = messages.CloudCdrPacker(SENSATION)
    rows = np.arange(18.0).reshape(3, 6)
    nan = rows.copy()
    nan[2, 4] = np.nan
    good = packer.pack(rows, "cmd/7", 42)
    cloud = messages.matrix_to_cloud(rows, SENSATION, messages.make_header("change/2", 9))
    return {
        "packed": (good, "cmd/7"),
        "rclpy_serialized": (serialize_message(cloud), "change/2"),
        "point_cloud": (cloud, "change/2"),
        "wrong_kind": (packer.pack(rows, "end/3"), "frame id 'end/3'"),
        "not_a_frame": (packer.pack(rows, "cmd/\u00b2"), "frame id 'cmd/²'"),
        "number_too_long": (packer.pack(rows, "cmd/" + "9" * 400), "frame id 'cmd/999"),
        "nan": (packer.pack(nan, "cmd/8"), "column 's4' holds NaN or inf"),
        # the frame id is checked before the data, as decode does
        "nan_and_not_a_frame": (packer.pack(nan, "x/8"), "frame id 'x/8'"),
        "truncated": (good[:-1], "data of 144 bytes overruns"),
        "tampered_point_cloud": (messages.matrix_to_cloud(nan, SENSATION,
                                                          messages.make_header("cmd/1")),
                                 "column 's4' holds NaN or inf"),
    }


@pytest.mark.parametrize("frame_id, parsed", [
    ("cmd/7", ("cmd", 7)), ("next/0", ("next", 0)), ("end/12", ("end", 12)),
    (f"change/{MAX_FRAME_NUMBER}", ("change", MAX_FRAME_NUMBER)),
    (f"change/{MAX_FRAME_NUMBER + 1}", None), ("cmd/" + "9" * 400, None),
    ("cmd/" + "0" * 20 + "1", None), ("cmd/\u00b2", None), ("cmd/-1", None), ("cmd/", None),
    ("bogus/1", None), ("change/1/2", None)])
def test_parse_frame_takes_the_protocol_grammar_only(frame_id, parsed):
    assert parse_frame(frame_id) == parsed


@pytest.mark.parametrize("name", _messages().keys())
def test_read_float_cloud_reads_and_drops_as_read_serialized_and_decode(context, name):
    msg, what = _messages()[name]
    kinds = ("cmd", "change")
    before, now = _node(context), _node(context)
    try:
        expected = _as_before(before, "/body/sensation", msg, kinds)
        assert _read(now, "/body/sensation", msg, kinds) == expected
        assert now.reasons == before.reasons
        if expected is None:
            assert len(now.reasons) == 1 and what in now.reasons[0][1]
        else:
            assert expected[1] == what and not now.reasons
            assert expected[3] == np.arange(18.0).tobytes()
    finally:
        before.destroy_node()
        now.destroy_node()


def test_now_ns_is_the_node_clocks_time(context):
    node = _node(context)
    try:
        before = node.get_clock().now().nanoseconds
        now = node.now_ns()
        assert before <= now <= node.get_clock().now().nanoseconds
        assert abs(now - time.time_ns()) < 5e9
    finally:
        node.destroy_node()


def test_now_ns_follows_simulated_time(context):
    node = GraphNode("sim_reader", context=context,
                     parameter_overrides=[*in_process.parameter_overrides(SMOKE),
                                          Parameter("use_sim_time", value=True)])
    try:
        clock = node.get_clock()
        assert clock.ros_time_is_active
        clock.set_ros_time_override(Time(nanoseconds=1_234_567_890_123,
                                         clock_type=clock.clock_type))
        assert node.now_ns() == clock.now().nanoseconds == 1_234_567_890_123
    finally:
        node.destroy_node()
