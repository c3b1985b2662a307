"""The committed sample bag (bags/sample_smoke): a launched smoke run (config/smoke.yaml)
copied without the bulky /body/* probing streams (copy_bag), ~170 KB, zstd chunks with CRCs."""
from __future__ import annotations

import numpy as np
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from sensorispace_ros.evaluation import analyze
from sensorispace_ros.recording.bag_reader import bag_info, read_bag_messages
from sensorispace_ros.recording.bag_verify import verify_bag
from sensorispace_ros import contracts, messages

from shared import REPO

SAMPLE = REPO / "bags" / "sample_smoke"


def test_sample_opens_with_both_readers_and_counts_agree():
    meta = yaml.safe_load((SAMPLE / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9
    meta_counts = {t["topic_metadata"]["name"]: t["message_count"]
                   for t in meta["topics_with_message_count"]}
    with AnyReader([SAMPLE], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        deserialised = sum(1 for c, _, raw in reader.messages()
                           if reader.deserialize(raw, c.msgtype) is not None)
    with open(SAMPLE / "sample_smoke.mcap", "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        decoded = sum(1 for _ in reader.iter_decoded_messages())
    mcap_counts = {summary.channels[c].topic: n
                   for c, n in summary.statistics.channel_message_counts.items()}
    assert mcap_counts == meta_counts
    assert deserialised == decoded == meta["message_count"] == sum(meta_counts.values())
    assert meta_counts["/representation/embedding"] > 0 and meta_counts["/agent/done"] == 1
    # in the bag format: zstd chunks, every CRC present and right
    assert verify_bag(SAMPLE).compression == "zstd"


def test_sample_rebuilds_the_recorded_embeddings():
    from sensorispace_ros.offline.representation import build_representation

    cfg = analyze.config_from_bag(SAMPLE)
    data = analyze.agent_data(SAMPLE)
    totals = analyze.agent_totals(SAMPLE)
    assert (len(data["ids"]), len(data["pairs"])) == (
        totals["points_of_view"], totals["compensation_rows"])
    representation = build_representation(
        data["povs"], data["pairs"], data["set_ids"], cfg, cfg["seed"])

    columns = contracts.contract("/representation/embedding").columns
    recorded = {}
    for _, _, _, msg in read_bag_messages(SAMPLE, ["/representation/embedding"]):
        recorded[msg.header.frame_id] = messages.cloud_to_table(msg, columns)
    assert len(recorded) == 2 * (cfg["representation"]["regularization"]["iterations"] + 1)
    for frame_id, table in recorded.items():
        dim, _, k = frame_id.split("/")
        stages = [representation.before[dim], *representation.iterations[dim]]
        n = int(dim[0])
        assert np.array_equal(table["pov"], data["ids"])
        got = np.stack([table[c] for c in ("x", "y", "z")[:n]], axis=1)
        np.testing.assert_allclose(got, stages[int(k)], rtol=0, atol=1e-9, err_msg=frame_id)


def test_a_bag_without_the_agent_records_is_analysed_without_naive_metrics():
    # The sample was recorded before /agent/pov_records, /agent/compensation_records and
    # /agent/stage_counters existed: analyze must say so, not fail on the missing topics.
    info = bag_info(SAMPLE)
    assert analyze.STAGE_COUNTERS not in info.topics and analyze.POV_RECORDS not in info.topics
    data = analyze.agent_data(SAMPLE)
    assert analyze.naive_records(SAMPLE, data, analyze.agent_totals(SAMPLE)) is None
