"""Bag writer, reader and recovery without ROS: format, independent readers, recovery
of a truncated MCAP, errors."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from sensorispace_ros.recording.bag_copy import copy_bag
from sensorispace_ros.recording.bag_format import (
    SESSION_CONFIG_TOPIC,
    SESSION_CONFIG_TYPE,
    BagError,
    session_config_cdr,
)
from sensorispace_ros.recording.bag_reader import (
    bag_info,
    check_contract,
    read_bag,
    read_session_config,
)
from sensorispace_ros.recording.bag_recovery import recover_bag
from sensorispace_ros.recording.bag_writer import BagWriter

STORE = get_typestore(Stores.ROS2_JAZZY)
SETTLED = "/agent/settled"
SENSATION = "/body/sensation"
TOPICS = {SETTLED: "std_msgs/msg/UInt64", SENSATION: "sensor_msgs/msg/PointCloud2",
          SESSION_CONFIG_TOPIC: SESSION_CONFIG_TYPE}


def read_ros2_messages(mcap_path: str):
    """(topic, decoded message) with mcap_ros2's decoder, independent of rosbags."""
    with open(mcap_path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        return [(channel.topic, decoded)
                for _, channel, _, decoded in reader.iter_decoded_messages()]


def settled_cdr(n: int) -> bytes:
    return bytes(STORE.serialize_cdr(STORE.types["std_msgs/msg/UInt64"](data=n),
                                     "std_msgs/msg/UInt64"))


def sensation_cdr(n: int) -> bytes:
    types = STORE.types
    fields = [types["sensor_msgs/msg/PointField"](name=f"s{k}", offset=8 * k, datatype=8, count=1)
              for k in range(6)]
    data = np.full(6, float(n)).view(np.uint8)
    cloud = types["sensor_msgs/msg/PointCloud2"](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=n, nanosec=0), frame_id=str(n)),
        height=1, width=1, fields=fields, is_bigendian=False, point_step=48, row_step=48,
        data=data, is_dense=True)
    return bytes(STORE.serialize_cdr(cloud, "sensor_msgs/msg/PointCloud2"))


def write_bag(path: Path, n: int, chunk_interval_s: float = 1.0, cut_at: int | None = None):
    """Bag of n settled + n sensation messages; returns the MCAP size when message
    cut_at was written and the number of messages in chunks closed by then."""
    cut = None
    with BagWriter(path, TOPICS, qos={SETTLED: {"reliability": "reliable",
                                                "history": "keep_all"}},
                   chunk_interval_s=chunk_interval_s) as writer:
        writer.write(SESSION_CONFIG_TOPIC, 1, session_config_cdr("seed: 3\n"))
        for i in range(n):
            writer.write(SETTLED, 10 + 2 * i, settled_cdr(i))
            writer.write(SENSATION, 11 + 2 * i, sensation_cdr(i))
            if i == cut_at:
                cut = (path / f"{path.name}.mcap").stat().st_size, \
                    1 + 2 * (i + 1) - writer.open_chunk_messages
    return cut


def test_bag_opens_with_both_independent_readers_and_counts_agree(tmp_path):
    bag = tmp_path / "run"
    write_bag(bag, 300)
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9 and meta["storage_identifier"] == "mcap"
    meta_counts = {t["topic_metadata"]["name"]: t["message_count"]
                   for t in meta["topics_with_message_count"]}
    assert meta_counts == {SETTLED: 300, SENSATION: 300, SESSION_CONFIG_TOPIC: 1}

    with open(bag / "run.mcap", "rb") as stream:
        reader = make_reader(stream)
        header, summary = reader.get_header(), reader.get_summary()
    assert header.profile == "ros2"
    assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
    assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
    mcap_counts = {summary.channels[cid].topic: n
                   for cid, n in summary.statistics.channel_message_counts.items()}
    assert mcap_counts == meta_counts

    with AnyReader([bag], default_typestore=STORE) as reader:
        values = [(c.topic, reader.deserialize(raw, c.msgtype))
                  for c, _, raw in reader.messages()]
    assert [m.data for t, m in values if t == SETTLED] == list(range(300))
    assert [m.header.frame_id for t, m in values if t == SENSATION] == [str(i) for i in range(300)]

    decoded = list(read_ros2_messages(str(bag / "run.mcap")))
    assert len(decoded) == 601
    assert [m.data for t, m in decoded if t == SETTLED] == list(range(300))


def test_read_bag_yields_exact_bytes_in_time_order(tmp_path):
    write_bag(tmp_path / "run", 50)
    rows = list(read_bag(tmp_path / "run", [SETTLED, SENSATION]))
    assert [r[2] for r in rows] == sorted(r[2] for r in rows)
    assert [r[3] for r in rows if r[0] == SETTLED] == [settled_cdr(i) for i in range(50)]
    assert [r[3] for r in rows if r[0] == SENSATION] == [sensation_cdr(i) for i in range(50)]
    assert read_session_config(tmp_path / "run") == "seed: 3\n"


def test_recover_truncated_mcap_keeps_every_message_of_closed_chunks(tmp_path):
    full = tmp_path / "full"
    # chunk_interval_s tiny: a chunk closes on nearly every write
    size, complete = write_bag(full, 2000, chunk_interval_s=1e-9, cut_at=1500)
    killed = tmp_path / "killed"
    killed.mkdir()
    # what a kill -9 leaves: the file as it was on disk at that moment, no metadata.yaml
    (killed / "killed.mcap").write_bytes((full / "full.mcap").read_bytes()[:size + 7])
    with pytest.raises(BagError, match="bag recover"):
        bag_info(killed)

    report = recover_bag(killed)
    assert report.truncated
    assert sum(report.counts.values()) >= complete
    assert (killed / "killed.mcap.truncated").exists()
    settled = [STORE.deserialize_cdr(cdr, t).data for _, t, _, cdr in read_bag(killed, [SETTLED])]
    assert settled == list(range(len(settled)))  # a prefix, nothing invented or reordered
    assert len(settled) >= (complete - 1) // 2
    meta = yaml.safe_load((killed / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    with open(killed / "killed.mcap", "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary.statistics.message_count == meta["message_count"] == sum(report.counts.values())
    assert len(list(read_ros2_messages(str(killed / "killed.mcap")))) == meta["message_count"]
    # a second recovery leaves the bag alone
    assert not recover_bag(killed).truncated


def test_recover_without_any_complete_chunk_is_a_one_line_error(tmp_path):
    write_bag(tmp_path / "full", 5)
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "broken.mcap").write_bytes((tmp_path / "full" / "full.mcap").read_bytes()[:40])
    with pytest.raises(BagError) as error:
        recover_bag(broken)
    assert "cannot be recovered" in str(error.value) and "\n" not in str(error.value)


def test_errors_are_one_line(tmp_path):
    write_bag(tmp_path / "good", 3)
    garbage = tmp_path / "garbage"
    shutil.copytree(tmp_path / "good", garbage)
    (garbage / "garbage.mcap").write_bytes(b"not an mcap at all" * 10)
    (garbage / "metadata.yaml").write_text(
        (tmp_path / "good" / "metadata.yaml").read_text().replace("good.mcap", "garbage.mcap"))
    cases = {
        tmp_path / "missing": "does not exist",
        garbage: "unreadable",
    }
    for path, expected in cases.items():
        with pytest.raises(BagError) as error:
            list(read_bag(path))
        assert expected in str(error.value) and "\n" not in str(error.value)
    with pytest.raises(BagError, match="another schema: topic /agent/settled has type"):
        check_contract(tmp_path / "good", {SETTLED: "std_msgs/msg/String"})
    with pytest.raises(BagError, match="another schema: none of its topics"):
        check_contract(tmp_path / "good", {"/other": "std_msgs/msg/String"})
    with pytest.raises(BagError, match="unknown message type"):
        BagWriter(tmp_path / "new", {"/x": "nope_msgs/msg/Nothing"})
    with pytest.raises(BagError, match="cannot create bag"):
        BagWriter(tmp_path / "good", TOPICS)


def test_copy_bag_keeps_chosen_topics_bytes_and_timestamps(tmp_path):
    write_bag(tmp_path / "full", 40)
    counts = copy_bag(tmp_path / "full", tmp_path / "part", [SETTLED, SESSION_CONFIG_TOPIC])
    assert counts == {SETTLED: 40, SESSION_CONFIG_TOPIC: 1}
    assert bag_info(tmp_path / "part").topics == {
        SETTLED: "std_msgs/msg/UInt64", SESSION_CONFIG_TOPIC: SESSION_CONFIG_TYPE}
    original = [r for r in read_bag(tmp_path / "full") if r[0] != SENSATION]
    assert list(read_bag(tmp_path / "part")) == original
    with pytest.raises(BagError, match="has no topic /nothing"):
        copy_bag(tmp_path / "full", tmp_path / "other", ["/nothing"])
