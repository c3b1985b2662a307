"""GraphNode's reading of the probe topics' bytes (read_float_cloud: the same
results and drop reasons as read_serialized + decode), its body description
(messages sized by the body wait for it; a malformed or a different one is
dropped) and its clock (now_ns: the node clock's time, simulated time
included). A node on a private context, no graph."""
import time

import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rclpy.time import Time

from sensorispace_ros import contracts, messages
from sensorispace_ros.core.body_description import BodyDescription
from sensorispace_ros.graph import framework, in_process
from sensorispace_ros.graph.framework import MAX_FRAME_NUMBER, GraphNode, parse_frame

from shared import SMOKE

PAPER_BODY = BodyDescription.revolute(4, 6)
SENSATION = messages.with_number_type(
    contracts.contract("/body/sensation").columns_for(PAPER_BODY), "float64")
KINDS = ("cmd", "change", "end")


def _node(context, described=True, **graph):
    node = GraphNode("reader", context=context,
                     parameter_overrides=in_process.parameter_overrides(SMOKE, graph))
    node.reasons = []
    node.drop = lambda topic, reason: node.reasons.append((topic, reason))
    if described:
        node.on_description(messages.description_to_msg(PAPER_BODY))
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


def _typed(kind):
    return dict.fromkeys(SENSATION, kind)


def _messages():
    packer = messages.CloudCdrPacker(SENSATION)
    rows = np.arange(18.0).reshape(3, 6)
    inf = rows.copy()
    inf[2, 4] = np.inf
    good = packer.pack(rows, "cmd/7", 42)
    cloud = messages.matrix_to_cloud(rows, SENSATION, messages.make_header("change/2", 9))
    mixed = messages.table_to_cloud({name: rows[:, k] for k, name in enumerate(SENSATION)},
                                    {**SENSATION, "s3": "float32"}, messages.make_header("cmd/9"))
    return {
        "packed": (good, "cmd/7"),
        "rclpy_serialized": (serialize_message(cloud), "change/2"),
        "point_cloud": (cloud, "change/2"),
        # a sensor's types: read as float64
        **{f"packed_{kind}": (messages.CloudCdrPacker(_typed(kind)).pack(rows, "cmd/3"), "cmd/3")
           for kind in ("float32", "uint16", "uint8")},
        "uint16_point_cloud": (messages.matrix_to_cloud(rows, _typed("uint16"),
                                                        messages.make_header("cmd/4")), "cmd/4"),
        "wrong_kind": (packer.pack(rows, "end/3"), "frame id 'end/3'"),
        "not_a_frame": (packer.pack(rows, "cmd/\u00b2"), "frame id 'cmd/²'"),
        "number_too_long": (packer.pack(rows, "cmd/" + "9" * 400), "frame id 'cmd/999"),
        "inf": (packer.pack(inf, "cmd/8"), "column 's4' holds inf"),
        # the frame id is checked before the data, as decode does
        "inf_and_not_a_frame": (packer.pack(inf, "x/8"), "frame id 'x/8'"),
        "truncated": (good[:-1], "data of 144 bytes overruns"),
        "tampered_point_cloud": (messages.matrix_to_cloud(inf, SENSATION,
                                                          messages.make_header("cmd/1")),
                                 "column 's4' holds inf"),
        "mismatched_field": (mixed, "field 's3'"),
        "not_a_number_type": (messages.CloudCdrPacker(dict.fromkeys(SENSATION, "int32")).pack(
            rows, "cmd/5"), "field 's0': datatype 5 is not one of"),
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


@pytest.mark.parametrize("kind", ["float64", "float32"])
def test_a_lost_frame_is_read_as_nan_not_dropped(context, kind):
    rows = np.arange(18.0).reshape(3, 6)
    rows[1] = np.nan
    node = _node(context)
    try:
        raw = messages.CloudCdrPacker(_typed(kind)).pack(rows, "cmd/2")
        cloud = messages.matrix_to_cloud(rows, _typed(kind), messages.make_header("cmd/2"))
        for msg in (raw, serialize_message(cloud)):
            parsed, cloud = node.read_float_cloud("/body/sensation", msg, KINDS)
            assert parsed == ("cmd", 2) and cloud.matrix.dtype == np.float64
            np.testing.assert_array_equal(cloud.matrix, rows)      # NaN where NaN
        assert not node.reasons
    finally:
        node.destroy_node()


def test_messages_sized_by_the_body_wait_for_its_description(context):
    node = _node(context, described=False)
    sized, got = [], []
    node._on_described = lambda description: sized.append(description)
    take = node.when_described("/body/sensation", got.append)
    small = BodyDescription(("a", "b"), "deg", (360.0, 360.0), 3)
    try:
        with pytest.raises(contracts.ContractError):
            node.columns_of("/body/sensation")
        take("first")
        take("second")
        assert got == [] and not sized
        bad = messages.description_to_msg(small)
        bad.header.frame_id = "deg/none"
        node.on_description(bad)                       # malformed: dropped, still waiting
        assert node.description is None and got == []
        node.on_description(messages.description_to_msg(small))
        assert sized == [small] and got == ["first", "second"]
        assert list(node.columns_of("/body/sensation")) == ["s0", "s1", "s2"]
        take("third")                                  # described: straight through
        assert got == ["first", "second", "third"]
        node.on_description(messages.description_to_msg(small))       # the same: nothing
        node.on_description(messages.description_to_msg(PAPER_BODY))  # another: dropped
        assert node.description == small and sized == [small]
        assert [topic for topic, _ in node.reasons] == ["/body/description"] * 2
        assert "differs" in node.reasons[1][1]
    finally:
        node.destroy_node()


def test_the_messages_waiting_for_the_description_are_bounded(context, monkeypatch):
    monkeypatch.setattr(framework, "MAX_WAITING", 3)
    node = _node(context, described=False)
    got = []
    take = node.when_described("/agent/points_of_view", got.append)
    try:
        for k in range(5):
            take(k)
        assert node.reasons == [("/agent/points_of_view",
                                 "more than 3 messages before the body description")] * 2
        node.on_description(messages.description_to_msg(PAPER_BODY))
        assert got == [0, 1, 2]
    finally:
        node.destroy_node()


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
