"""``sensorispace bag verify``: a closed bag's every CRC, and its counts and times
against metadata.yaml and the MCAP Statistics record.

Checks, in order: the data section record by record (each chunk's CRC,
decompression and message indexes, then the data section CRC;
recording.bag_integrity), the summary CRC, the summary (Statistics, chunk
indexes, channels) against what the data section holds, and metadata.yaml
against both. The first difference is a one-line BagError.
"""
from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import yaml

from sensorispace_ros.recording.bag_format import BagError, one_line
from sensorispace_ros.recording.bag_integrity import (
    DataScan,
    Summary,
    read_summary,
    scan_data_section,
)
from sensorispace_ros.recording.bag_reader import the_mcap_file


@dataclass(frozen=True)
class VerifyReport:
    path: Path
    messages: int
    topics: int
    chunks: int
    compression: str

    def summary(self) -> str:
        chunks = f"{self.chunks} {self.compression} chunk" + ("" if self.chunks == 1 else "s")
        return (f"{self.path}: OK: {self.messages} messages on {self.topics} topics in {chunks}; "
                f"chunk, data section and summary CRCs correct; counts and times agree with "
                f"metadata.yaml and the Statistics record")


def verify_bag(bag_dir: str | os.PathLike) -> VerifyReport:
    path = Path(bag_dir)
    mcap = the_mcap_file(path)
    meta = _metadata(path)
    scan = scan_data_section(mcap, strict=True)
    _check_message_indexes(mcap, scan)
    summary = read_summary(mcap)
    _check_summary(mcap, scan, summary)
    try:
        _check_metadata(path, meta, mcap, scan)
    except (KeyError, TypeError, IndexError) as exc:
        raise BagError(f"{path / 'metadata.yaml'} lacks or garbles the field "
                       f"{one_line(exc)}") from None
    compressions = {index.compression or "uncompressed" for index in summary.chunk_indexes}
    return VerifyReport(path, scan.message_count, len(scan.channels), len(scan.chunks),
                        "/".join(sorted(compressions)) or "no")


def _metadata(path: Path) -> dict:
    file = path / "metadata.yaml"
    if not file.is_file():
        raise BagError(f"bag {path} has no metadata.yaml (not closed cleanly? "
                       f"run `sensorispace bag recover {path}`)")
    try:
        return yaml.safe_load(file.read_text())["rosbag2_bagfile_information"]
    except Exception as exc:
        raise BagError(f"{file} is not rosbag2 metadata: {one_line(exc)}") from None


def _check_message_indexes(mcap: Path, scan: DataScan) -> None:
    for number, chunk in enumerate(scan.chunks, 1):
        if chunk.indexed != chunk.counts:
            raise BagError(f"{mcap}: the message indexes of chunk {number} (offset {chunk.offset}) "
                           f"list {sum(chunk.indexed.values())} messages, the chunk holds "
                           f"{sum(chunk.counts.values())}")


def _differ(mcap: Path, what: str, found, expected) -> None:
    if found != expected:
        raise BagError(f"{mcap}: {what} is {found}, the data section holds {expected}")


def _check_summary(mcap: Path, scan: DataScan, summary: Summary) -> None:
    stats = summary.statistics
    if stats is None:
        raise BagError(f"{mcap}: the summary has no Statistics record")
    topic = {cid: channel.topic for cid, channel in scan.channels.items()}
    _differ(mcap, "the summary's channel list",
            sorted(c.topic for c in summary.channels.values()), sorted(topic.values()))
    _differ(mcap, "the Statistics message count", stats.message_count, scan.message_count)
    for cid, count in {**dict.fromkeys(stats.channel_message_counts, 0), **scan.counts}.items():
        _differ(mcap, f"the Statistics count of {topic.get(cid, f'channel {cid}')}",
                stats.channel_message_counts.get(cid, 0), count)
    _differ(mcap, "the Statistics chunk count", stats.chunk_count, len(scan.chunks))
    _differ(mcap, "the Statistics channel count", stats.channel_count, len(scan.channels))
    _differ(mcap, "the Statistics schema count", stats.schema_count, len(scan.schemas))
    if scan.message_count:
        _differ(mcap, "the Statistics start time", stats.message_start_time, scan.start)
        _differ(mcap, "the Statistics end time", stats.message_end_time, scan.end)
    _differ(mcap, "the chunk index's chunk offsets",
            [index.chunk_start_offset for index in summary.chunk_indexes],
            [chunk.offset for chunk in scan.chunks])


def _check_metadata(path: Path, meta: dict, mcap: Path, scan: DataScan) -> None:
    file = path / "metadata.yaml"

    def differ(what: str, found, expected) -> None:
        if found != expected:
            raise BagError(f"{file}: {what} is {found}, {mcap.name} holds {expected}")

    differ("storage_identifier", meta.get("storage_identifier"), "mcap")
    differ("relative_file_paths", meta.get("relative_file_paths"), [mcap.name])
    for key in ("compression_format", "compression_mode"):
        # the chunks' compression is inside the storage: rosbag2 must not undo anything
        differ(key, repr(meta.get(key) or ""), repr(""))
    start = scan.start if scan.message_count else None
    duration = scan.end - scan.start if scan.message_count else 0
    differ("message_count", meta.get("message_count"), scan.message_count)
    if start is not None:
        differ("starting_time", meta["starting_time"]["nanoseconds_since_epoch"], start)
    differ("duration", meta["duration"]["nanoseconds"], duration)
    by_topic = Counter()
    types = {}
    for cid, channel in scan.channels.items():
        by_topic[channel.topic] += scan.counts.get(cid, 0)
        schema = scan.schemas.get(channel.schema_id)
        types[channel.topic] = schema.name if schema else None
    listed = {t["topic_metadata"]["name"]: t for t in meta.get("topics_with_message_count", [])}
    differ("the topic list", sorted(listed), sorted(types))
    for name, entry in listed.items():
        differ(f"the message count of {name}", entry["message_count"], by_topic[name])
        differ(f"the type of {name}", entry["topic_metadata"]["type"], types[name])
    files = meta.get("files") or []
    differ("the files list", [f.get("path") for f in files], [mcap.name])
    differ("the message count of files[0]", files[0].get("message_count"), scan.message_count)
    if start is not None:
        differ("the starting time of files[0]",
               files[0]["starting_time"]["nanoseconds_since_epoch"], start)
    differ("the duration of files[0]", files[0]["duration"]["nanoseconds"], duration)
