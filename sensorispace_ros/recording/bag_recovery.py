"""Recovery of the bag a killed recorder left behind (``sensorispace bag recover``).

A recorder killed with -9 leaves an MCAP without summary and no
``metadata.yaml``. ``recover_bag`` rebuilds a normal bag from every complete
chunk plus the write-ahead log's complete records (recording.bag_writer; a
record also found in the last chunk, killed between the chunk flush and the
log truncation, is kept once).
"""
from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from sensorispace_ros.recording.bag_format import BagError, one_line, typestore
from sensorispace_ros.recording.bag_reader import bag_info, mcap_files, open_reader
from sensorispace_ros.recording.bag_writer import WAL_NAME, BagWriter, read_write_ahead_log


@dataclass(frozen=True)
class RecoveryReport:
    path: Path
    counts: dict[str, int]
    recovered_from: Path | None  # the truncated original kept beside the new file
    truncated: bool

    def summary(self) -> str:
        total = sum(self.counts.values())
        state = "recovered" if self.truncated else "already complete"
        return f"{self.path}: {state}, {total} messages on {len(self.counts)} topics"


def _bag_is_complete(bag_dir: Path) -> bool:
    if not (bag_dir / "metadata.yaml").is_file():
        return False
    try:
        reader = open_reader(bag_dir)
    except BagError:
        return False
    reader.close()
    return all(_mcap_has_summary(p) for p in mcap_files(bag_dir))


def _mcap_has_summary(path: Path) -> bool:
    from mcap.reader import make_reader

    try:
        with path.open("rb") as stream:
            summary = make_reader(stream).get_summary()
    except Exception:
        return False
    return summary is not None and summary.statistics is not None


def _scan_truncated_mcap(path: Path):
    """Schemas, channels and messages of every complete record before the damage."""
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader

    schemas, channels, messages = {}, {}, []
    with path.open("rb") as stream:
        try:
            for record in StreamReader(stream, skip_magic=False).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    messages.append((record.log_time, record.channel_id, record.data))
        except Exception as exc:  # EndOfFile, struct.error, ... at the truncation point
            if not messages and not channels:
                raise BagError(
                    f"{path} cannot be recovered: no complete chunk before the damage "
                    f"({one_line(exc)})"
                ) from None
    return schemas, channels, messages


def _add_logged_messages(messages: list, channels: dict, wal: Path, original: Path) -> None:
    """Append the write-ahead log's records that no complete chunk holds."""
    channel_of_topic = {channel.topic: cid for cid, channel in channels.items()}
    in_chunks = set(messages)
    for topic, log_time, data in read_write_ahead_log(wal):
        cid = channel_of_topic.get(topic)
        if cid is None:
            raise BagError(f"{wal} names topic {topic}, which {original} does not declare")
        if (log_time, cid, data) not in in_chunks:
            messages.append((log_time, cid, data))


def _topics_and_qos(schemas: dict, channels: dict, original: Path) -> tuple[dict, dict]:
    """Each channel's ROS type and offered QoS; BagError if it is not ros2 CDR."""
    from rosbags.rosbag2.metadata import parse_qos

    store = typestore()
    topics, qos = {}, {}
    for channel in channels.values():
        schema = schemas.get(channel.schema_id)
        if schema is None or channel.message_encoding != "cdr":
            raise BagError(f"{original} is of another schema: channel {channel.topic} "
                           "is not ros2 cdr")
        if schema.name not in store.types:
            raise BagError(f"{original} is of another schema: unknown type {schema.name}")
        topics[channel.topic] = schema.name
        offered = channel.metadata.get("offered_qos_profiles")
        qos[channel.topic] = parse_qos(offered) if offered else []
    return topics, qos


def recover_bag(bag_dir: str | os.PathLike) -> RecoveryReport:
    """Rebuild a readable bag from the MCAP a killed recorder left behind.

    Every message of every complete chunk is kept (re-written with its original
    timestamp and bytes into a fresh MCAP with summary + Statistics and a
    matching metadata.yaml), and every complete record of the write-ahead log
    (``WAL_NAME``) not already in a chunk; the damaged original stays beside it
    as ``<name>.mcap.truncated``. A bag that is already complete is left alone
    (a stale log in it is removed).
    """
    from mcap.exceptions import McapError

    path = Path(bag_dir)
    if not path.is_dir():
        raise BagError(f"bag {path} does not exist or is not a directory")
    files = mcap_files(path)
    if len(files) != 1:
        raise BagError(f"bag {path} must hold exactly one .mcap file, found {len(files)}")
    original, wal = files[0], path / WAL_NAME
    if _bag_is_complete(path):
        wal.unlink(missing_ok=True)
        return RecoveryReport(path, bag_info(path).counts, None, truncated=False)
    try:
        schemas, channels, messages = _scan_truncated_mcap(original)
    except McapError as exc:
        raise BagError(f"{original} cannot be recovered: {one_line(exc)}") from None
    _add_logged_messages(messages, channels, wal, original)
    topics, qos = _topics_and_qos(schemas, channels, original)
    kept = original.with_name(original.name + ".truncated")
    counts = _rewrite(path, original, kept, topics, qos, channels, messages)
    return RecoveryReport(path, counts, kept, truncated=True)


def _rewrite(path: Path, original: Path, kept: Path, topics: dict, qos: dict,
             channels: dict, messages: list) -> dict:
    """Write ``messages`` into a fresh bag staged beside ``path``, then put it in the
    place of the damaged ``original`` (moved to ``kept``) and of the write-ahead
    log (kept as ``.recovered``). Returns the counts."""
    wal = path / WAL_NAME
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=f".{path.name}.recover-") as tmp:
        staged = Path(tmp) / path.name
        writer = BagWriter(staged, topics, qos=qos)
        id_to_topic = {cid: ch.topic for cid, ch in channels.items()}
        for log_time, channel_id, data in sorted(messages, key=lambda m: m[0]):
            writer.write(id_to_topic[channel_id], log_time, data)
        counts = dict(writer.counts)
        writer.close()
        original.replace(kept)
        if wal.is_file():
            wal.replace(path / (WAL_NAME + ".recovered"))
        # the rebuilt file is <dir>.mcap (rosbags' name), metadata.yaml lists it
        for produced in staged.iterdir():
            shutil.move(str(produced), str(path / produced.name))
    return counts
