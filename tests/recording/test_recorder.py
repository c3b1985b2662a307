"""The recorder node in its own process: no drops, clean SIGTERM, kill -9 + recover."""
from __future__ import annotations

import os
import re
import signal
import time

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from sensorispace_ros.recording.bag_reader import bag_info, read_bag, read_session_config
from sensorispace_ros.recording.bag_recovery import recover_bag
from sensorispace_ros.recording.bag_verify import verify_bag

from bag_test_support import PARAMS_FILE, wait_for

pytestmark = pytest.mark.slow

SENSATION, SETTLED, JOINTS = "/body/sensation", "/agent/settled", "/body/joint_states"
STORE = get_typestore(Stores.ROS2_JAZZY)


def start_recorder(children, ros_env, tmp_path, chunk_interval_s=0.2):
    params = tmp_path / "params.yaml"
    params.write_text(PARAMS_FILE)
    bag = tmp_path / "bag"
    process = children(["-m", "sensorispace_ros.graph.nodes.recorder", "--ros-args",
                        "--params-file", str(params), "-p", f"graph.bag_dir:={bag}",
                        "-p", f"recorder.chunk_interval_s:={chunk_interval_s}"], ros_env["env"])
    return process, bag


class Publishers:
    """Contract publishers for three topics, in a private context."""

    def __init__(self, context):
        from rclpy.node import Node

        from sensorispace_ros import contracts

        self.node = Node("test_publisher", context=context)
        self.pub = {t: contracts.create_publisher(self.node, t) for t in (SENSATION, SETTLED, JOINTS)}
        self.sent = {t: 0 for t in self.pub}

    def wait_matched(self, timeout_s=30.0):
        wait_for(lambda: all(p.get_subscription_count() >= 1 for p in self.pub.values()),
                 timeout_s, "the recorder's subscriptions")

    def publish_round(self, i: int) -> None:
        from std_msgs.msg import UInt64

        from sensorispace_ros import contracts, messages

        from sensorispace_ros.core.body_description import BodyDescription

        body = BodyDescription.revolute(4, 6)
        header = messages.make_header(str(i), i)
        self.pub[SENSATION].publish(messages.matrix_to_cloud(
            np.full((1, 6), float(i)), contracts.contract(SENSATION).columns_for(body), header))
        self.pub[SETTLED].publish(UInt64(data=i))
        self.sent[SENSATION] += 1
        self.sent[SETTLED] += 1
        if i % 4 == 0:
            self.pub[JOINTS].publish(messages.motor_to_joint_state(np.full(4, i * 1e-3), header,
                                                                   body.joint_names))
            self.sent[JOINTS] += 1

    def wait_acked(self):
        from rclpy.duration import Duration

        for publisher in self.pub.values():
            assert publisher.wait_for_all_acked(Duration(seconds=20))


def test_recorder_records_every_message_and_closes_cleanly_on_sigterm(
        ros_env, ros_context, children, tmp_path):
    recorder, bag = start_recorder(children, ros_env, tmp_path)
    publishers = Publishers(ros_context)
    publishers.wait_matched()
    rounds = 3000
    started = time.monotonic()
    for i in range(rounds):
        publishers.publish_round(i)
    publishers.wait_acked()
    publish_s = time.monotonic() - started
    os.kill(recorder.pid, signal.SIGTERM)
    output, _ = recorder.communicate(timeout=30)
    assert recorder.returncode == 0, output

    info = bag_info(bag)
    for topic, sent in publishers.sent.items():
        assert info.counts[topic] == sent, (topic, info.counts[topic], sent)
    with AnyReader([bag], default_typestore=STORE) as reader:
        settled = [reader.deserialize(raw, c.msgtype).data
                   for c, _, raw in reader.messages() if c.topic == SETTLED]
        frames = [reader.deserialize(raw, c.msgtype).header.frame_id
                  for c, _, raw in reader.messages() if c.topic == SENSATION]
    assert settled == list(range(rounds))
    assert frames == [str(i) for i in range(rounds)]
    with open(bag / "bag.mcap", "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        decoded = sum(1 for _ in reader.iter_decoded_messages())
    assert decoded == sum(info.counts.values())
    # MCAP's Statistics lists the channels that hold messages
    assert {summary.channels[c].topic: n
            for c, n in summary.statistics.channel_message_counts.items()} == {
                topic: n for topic, n in info.counts.items() if n}
    assert verify_bag(bag).messages == sum(info.counts.values())
    # the run's configuration travels in the bag
    config = yaml.safe_load(read_session_config(bag))["/**"]["ros__parameters"]
    assert config["seed"] == 7 and config["world"]["grid_count"] == 5
    rate = re.search(r"\(([0-9]+) msgs/s sustained\)", output)
    assert rate, output
    print(f"recorder sustained {rate.group(1)} msgs/s; publisher side "
          f"{sum(publishers.sent.values()) / publish_s:.0f} msgs/s")


def test_recorder_killed_with_sigkill_is_recoverable_up_to_the_last_closed_chunk(
        ros_env, ros_context, children, tmp_path):
    chunk_interval_s = 0.2
    recorder, bag = start_recorder(children, ros_env, tmp_path, chunk_interval_s)
    publishers = Publishers(ros_context)
    publishers.wait_matched()
    for i in range(1000):
        publishers.publish_round(i)
    publishers.wait_acked()
    # acknowledged = in the recorder's hands; after a few chunk intervals its chunk is on disk
    time.sleep(5 * chunk_interval_s + 0.5)
    on_disk = dict(publishers.sent)
    for i in range(1000, 1500):  # still in flight / in the open chunk when killed
        publishers.publish_round(i)
    os.kill(recorder.pid, signal.SIGKILL)
    recorder.wait(timeout=10)
    assert not (bag / "metadata.yaml").exists()

    report = recover_bag(bag)
    assert report.truncated
    assert verify_bag(bag).messages == sum(report.counts.values())
    for topic, count in on_disk.items():
        assert report.counts[topic] >= count, (topic, report.counts[topic], count)
    settled = [STORE.deserialize_cdr(cdr, t).data for _, t, _, cdr in read_bag(bag, [SETTLED])]
    assert settled == list(range(len(settled)))
    with AnyReader([bag], default_typestore=STORE) as reader:
        assert sum(1 for c, _, raw in reader.messages()
                   if reader.deserialize(raw, c.msgtype) is not None) == sum(report.counts.values())
    assert read_session_config(bag).startswith("/**:")
    print(f"recovered {report.counts} (>= {on_disk} acknowledged before the last chunk closed)")


def test_recorder_restarted_after_sigkill_merges_both_parts(ros_env, ros_context, children, tmp_path):
    chunk_interval_s = 0.2
    recorder, bag = start_recorder(children, ros_env, tmp_path, chunk_interval_s)
    publishers = Publishers(ros_context)
    publishers.wait_matched()
    for i in range(400):
        publishers.publish_round(i)
    publishers.wait_acked()
    time.sleep(5 * chunk_interval_s + 0.5)
    os.kill(recorder.pid, signal.SIGKILL)
    recorder.wait(timeout=10)
    wait_for(lambda: all(p.get_subscription_count() == 0 for p in publishers.pub.values()),
             30, "the killed recorder to leave the graph")

    restarted, _ = start_recorder(children, ros_env, tmp_path, chunk_interval_s)
    publishers.wait_matched()
    for i in range(400, 800):
        publishers.publish_round(i)
    publishers.wait_acked()
    os.kill(restarted.pid, signal.SIGTERM)
    output, _ = restarted.communicate(timeout=30)
    assert restarted.returncode == 0, output

    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith("bag")) == ["bag"]
    settled = [STORE.deserialize_cdr(cdr, t).data for _, t, _, cdr in read_bag(bag, [SETTLED])]
    assert settled == list(range(800))  # both parts, nothing lost, in order
    info = bag_info(bag)
    assert info.counts[SENSATION] == 800 and info.counts[JOINTS] == 200
    assert read_session_config(bag).startswith("/**:")
