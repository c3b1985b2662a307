"""The bag's MCAP: zstd chunks and every CRC, checked independently of our reader;
`bag verify` passes on a bag and names one flipped byte; recovery drops a chunk
cut short or failing its CRC, and says so."""
from __future__ import annotations

import shutil
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
import yaml
import zstandard
from mcap.reader import make_reader
from mcap.records import Chunk, DataEnd, Footer
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from sensorispace_ros.cli import main as cli
from sensorispace_ros.recording.bag_format import BagError
from sensorispace_ros.recording.bag_reader import read_bag
from sensorispace_ros.recording.bag_recovery import recover_bag
from sensorispace_ros.recording.bag_verify import verify_bag
from sensorispace_ros.recording.bag_writer import BagWriter

STORE = get_typestore(Stores.ROS2_JAZZY)
SETTLED, SENSATION = "/agent/settled", "/body/sensation"
TOPICS = {SETTLED: "std_msgs/msg/UInt64", SENSATION: "sensor_msgs/msg/PointCloud2"}
ROUNDS = 3000


def settled_cdr(n: int) -> bytes:
    return bytes(STORE.serialize_cdr(STORE.types["std_msgs/msg/UInt64"](data=n),
                                     "std_msgs/msg/UInt64"))


def sensation_cdr(n: int, rows: int) -> bytes:
    """A PointCloud2 of ``rows`` x 6 float64, values drawn from a seed (like sensations:
    little to compress in the numbers, much in the framing)."""
    types = STORE.types
    fields = [types["sensor_msgs/msg/PointField"](name=f"s{k}", offset=8 * k, datatype=8, count=1)
              for k in range(6)]
    values = np.random.default_rng(n).random((rows, 6))
    cloud = types["sensor_msgs/msg/PointCloud2"](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=n, nanosec=0), frame_id=f"change/{n}"),
        height=1, width=rows, fields=fields, is_bigendian=False, point_step=48,
        row_step=48 * rows, data=values.view(np.uint8).ravel(), is_dense=True)
    return bytes(STORE.serialize_cdr(cloud, "sensor_msgs/msg/PointCloud2"))


def sent(n: int) -> list[tuple[str, int, bytes]]:
    return [(SETTLED, 10 + 2 * n, settled_cdr(n)), (SENSATION, 11 + 2 * n, sensation_cdr(n, 1 + n % 40))]


@pytest.fixture(scope="module")
def bag(tmp_path_factory) -> Path:
    """A bag of several chunks (about 5 MB of messages, 1 MiB chunks)."""
    path = tmp_path_factory.mktemp("bags") / "run"
    with BagWriter(path, TOPICS) as writer:
        for n in range(ROUNDS):
            for topic, stamp, cdr in sent(n):
                writer.write(topic, stamp, cdr)
    return path


def chunk_records(mcap: Path) -> list[Chunk]:
    with mcap.open("rb") as stream:
        return [r for r in StreamReader(stream, emit_chunks=True).records if isinstance(r, Chunk)]


def test_every_chunk_is_zstd_with_its_crc_and_every_crc_is_right(bag):
    mcap = bag / "run.mcap"
    chunks = chunk_records(mcap)
    assert len(chunks) >= 4
    for chunk in chunks:
        assert chunk.compression == "zstd" and chunk.uncompressed_crc != 0
        raw = zstandard.decompress(chunk.data, chunk.uncompressed_size)
        assert len(raw) == chunk.uncompressed_size and zlib.crc32(raw) == chunk.uncompressed_crc
    # at the level docs/bags.md names (3)
    assert zstandard.ZstdCompressor(level=3).compress(raw) == chunk.data
    assert sum(len(c.data) for c in chunks) < sum(c.uncompressed_size for c in chunks)
    data = mcap.read_bytes()
    # the data section CRC and the chunk CRCs, checked by mcap's own stream reader
    records = list(StreamReader(str(mcap), validate_crcs=True).records)
    data_end = next(r for r in records if isinstance(r, DataEnd))
    footer = next(r for r in records if isinstance(r, Footer))
    assert data_end.data_section_crc != 0
    # the data section CRC covers the magic up to the DataEnd record: recomputed here
    data_end_at = footer.summary_start - (9 + 4)
    assert data[data_end_at] == 0x0F
    assert zlib.crc32(data[:data_end_at]) == data_end.data_section_crc
    # the summary CRC: the summary section and the footer up to its summary_offset_start
    assert footer.summary_crc != 0
    assert zlib.crc32(data[footer.summary_start:len(data) - 8 - 4]) == footer.summary_crc


def test_both_independent_readers_read_every_message(bag):
    expected = [m for n in range(ROUNDS) for m in sent(n)]
    with AnyReader([bag], default_typestore=STORE) as reader:
        read = [(c.topic, t, bytes(raw)) for c, t, raw in reader.messages()]
        assert all(reader.deserialize(raw, c.msgtype) is not None
                   for c, _, raw in reader.messages())
    assert read == expected
    with open(bag / "run.mcap", "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()], validate_crcs=True)
        decoded = [(channel.topic, message.log_time, message.data)
                   for _, channel, message, _ in reader.iter_decoded_messages(log_time_order=True)]
    assert decoded == expected


def test_metadata_says_the_chunks_are_inside_the_storage(bag):
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9 and meta["storage_identifier"] == "mcap"
    # rosbag2's own (file or message) compression is not used: readers must not undo any
    assert meta["compression_format"] == "" and meta["compression_mode"] == ""
    assert meta["custom_data"]["mcap_chunk_compression"] == "zstd"
    assert meta["message_count"] == 2 * ROUNDS
    assert meta["starting_time"]["nanoseconds_since_epoch"] == 10
    assert meta["duration"]["nanoseconds"] == 11 + 2 * (ROUNDS - 1) - 10


def test_bag_verify_passes(bag, capsys):
    assert cli.main(["bag", "verify", str(bag)]) == 0
    out = capsys.readouterr().out.strip()
    assert len(out.splitlines()) == 1 and f"{2 * ROUNDS} messages on 2 topics" in out
    assert verify_bag(bag).chunks == len(chunk_records(bag / "run.mcap"))


def damaged_copy(bag: Path, target: Path, offset: int) -> Path:
    shutil.copytree(bag, target)
    mcap = target / "run.mcap"
    data = bytearray(mcap.read_bytes())
    data[offset] ^= 0x01
    mcap.write_bytes(bytes(data))
    return target


def payload_offsets(mcap: Path) -> list[int]:
    """Offset of the middle byte of each chunk's compressed data."""
    with mcap.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    offsets = []
    for index in summary.chunk_indexes:
        # record head, 3 x u64 + u32, compression string, compressed size
        start = index.chunk_start_offset + 9 + 28 + 4 + len(index.compression) + 8
        offsets.append(start + index.compressed_size // 2)
    return offsets


def verify_error(path: Path, capsys) -> str:
    assert cli.main(["bag", "verify", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_bag_verify_names_one_flipped_payload_byte(bag, tmp_path, capsys):
    offset = payload_offsets(bag / "run.mcap")[2]
    error = verify_error(damaged_copy(bag, tmp_path / "flipped", offset), capsys)
    assert "chunk 3 " in error and ("CRC mismatch" in error or "does not decompress" in error)
    # the readers that check chunk CRCs refuse it too
    with pytest.raises(BagError, match="unreadable"):
        list(read_bag(tmp_path / "flipped"))


def test_bag_verify_names_a_flipped_byte_outside_the_chunks(bag, tmp_path, capsys):
    data = (bag / "run.mcap").read_bytes()
    (summary_start,) = struct.unpack_from("<Q", data, len(data) - 8 - 20)
    error = verify_error(damaged_copy(bag, tmp_path / "summary", summary_start + 30), capsys)
    assert "summary CRC mismatch" in error
    with pytest.raises(BagError, match="summary CRC mismatch"):
        list(read_bag(tmp_path / "summary"))
    # a message index sits between chunks: only the data section CRC covers it
    with (bag / "run.mcap").open("rb") as stream:
        chunk_index = make_reader(stream).get_summary().chunk_indexes[0]
    # record head, channel id, entries length, then the first entry's log time
    first_entry = min(chunk_index.message_index_offsets.values()) + 9 + 2 + 4
    error = verify_error(damaged_copy(bag, tmp_path / "index", first_entry + 3), capsys)
    assert "data section CRC mismatch" in error


def test_bag_verify_names_counts_that_disagree_with_metadata(bag, tmp_path, capsys):
    shutil.copytree(bag, tmp_path / "meta")
    meta = tmp_path / "meta" / "metadata.yaml"
    meta.write_text(meta.read_text().replace(f"message_count: {ROUNDS}\n", f"message_count: {ROUNDS + 1}\n", 1))
    error = verify_error(tmp_path / "meta", capsys)
    assert "metadata.yaml" in error and "message count of" in error


def test_recovery_drops_a_torn_chunk_and_one_failing_its_crc_with_a_message(bag, tmp_path):
    mcap = bag / "run.mcap"
    with mcap.open("rb") as stream:
        indexes = make_reader(stream).get_summary().chunk_indexes
    # killed while the last chunk was being written: it is cut in the middle
    cut = indexes[-1].chunk_start_offset + indexes[-1].chunk_length // 2
    killed = tmp_path / "killed"
    killed.mkdir()
    data = bytearray(mcap.read_bytes()[:cut])
    data[payload_offsets(mcap)[1]] ^= 0x01           # and chunk 2 damaged
    (killed / "killed.mcap").write_bytes(bytes(data))

    report = recover_bag(killed)
    assert report.truncated and len(report.dropped) == 2
    assert f"chunk 2 (offset {indexes[1].chunk_start_offset})" in report.dropped[0]
    assert f"chunk at offset {indexes[-1].chunk_start_offset} is cut short" in report.dropped[1]
    summary = report.summary().splitlines()
    assert len(summary) == 3 and summary[1].startswith(f"{killed}: dropped: chunk 2")

    kept = [i for i in range(len(indexes) - 1) if i != 1]
    expected = sum(sum(_chunk_counts(mcap, indexes[i]).values()) for i in kept)
    assert sum(report.counts.values()) == expected
    # what is kept is exactly the messages of the intact chunks, and the bag verifies
    assert verify_bag(killed).messages == expected
    stamps = {t for _, _, t, _ in read_bag(killed)}
    assert all(indexes[i].message_start_time in stamps for i in kept)
    assert indexes[1].message_start_time not in stamps


def _chunk_counts(mcap: Path, index) -> dict[int, int]:
    """Messages per channel of one chunk, from its message index records."""
    with mcap.open("rb") as stream:
        counts = {}
        for channel_id, offset in index.message_index_offsets.items():
            stream.seek(offset + 9 + 2)
            (length,) = struct.unpack("<I", stream.read(4))
            counts[channel_id] = length // 16
    return counts
