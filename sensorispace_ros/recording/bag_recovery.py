"""Recovery of the bag a killed recorder left behind (``sensorispace bag recover``).

A recorder killed with -9 leaves an MCAP without summary and no
``metadata.yaml``. ``recover_bag`` rebuilds a normal bag from every complete
chunk whose CRC is right plus the write-ahead log's complete records
(recording.bag_writer; a record also found in a kept chunk, killed between the
chunk flush and the log truncation, is kept once). A chunk cut short by the
kill, or one that fails its CRC, is dropped and named in the report.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from sensorispace_ros.recording.bag_format import BagError, typestore
from sensorispace_ros.recording.bag_integrity import DamagedMcap, scan_data_section
from sensorispace_ros.recording.bag_reader import bag_info, mcap_files, open_reader, the_mcap_file
from sensorispace_ros.recording.bag_writer import WAL_NAME, BagWriter, read_write_ahead_log


@dataclass(frozen=True)
class RecoveryReport:
    path: Path
    counts: dict[str, int]
    recovered_from: Path | None  # the truncated original kept beside the new file
    truncated: bool
    dropped: list[str] = field(default_factory=list)  # what was left out, and why

    def summary(self) -> str:
        total = sum(self.counts.values())
        state = "recovered" if self.truncated else "already complete"
        lines = [f"{self.path}: {state}, {total} messages on {len(self.counts)} topics"]
        lines += [f"{self.path}: dropped: {reason}" for reason in self.dropped]
        return "\n".join(lines)


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


def _catalogue(scan, wal_catalogue: dict, original: Path) -> dict[int, tuple[str, str, str]]:
    """channel id -> (topic, type, offered QoS) from the MCAP's channels, completed
    by the write-ahead log's catalogue; BagError if a channel is not ros2 CDR."""
    catalogue = {entry["channel_id"]: (topic, entry["type"], entry["offered_qos_profiles"])
                 for topic, entry in wal_catalogue.items()}
    for cid, channel in scan.channels.items():
        schema = scan.schemas.get(channel.schema_id)
        if schema is None or channel.message_encoding != "cdr":
            raise BagError(f"{original} is of another schema: channel {channel.topic} is not ros2 cdr")
        catalogue[cid] = (channel.topic, schema.name,
                          channel.metadata.get("offered_qos_profiles", ""))
    store = typestore()
    for topic, msgtype, _ in catalogue.values():
        if msgtype not in store.types:
            raise BagError(f"{original} is of another schema: unknown type {msgtype}")
    return catalogue


def _add_logged_messages(messages: list, catalogue: dict, records: list, wal: Path,
                         original: Path) -> None:
    """Append the write-ahead log's records that no kept chunk holds."""
    channel_of_topic = {topic: cid for cid, (topic, _, _) in catalogue.items()}
    in_chunks = set(messages)
    for topic, log_time, data in records:
        cid = channel_of_topic.get(topic)
        if cid is None:
            raise BagError(f"{wal} names topic {topic}, which {original} does not declare")
        if (log_time, cid, data) not in in_chunks:
            messages.append((log_time, cid, data))


def recover_bag(bag_dir: str | os.PathLike) -> RecoveryReport:
    """Rebuild a readable bag from the MCAP a killed recorder left behind.

    Every message of every complete chunk with a correct CRC is kept (re-written
    with its original timestamp and bytes into a fresh MCAP with summary +
    Statistics and a matching metadata.yaml), and every complete record of the
    write-ahead log (``WAL_NAME``) not already in a chunk; the damaged original
    stays beside it as ``<name>.mcap.truncated``. A bag that is already complete
    is left alone (a stale log in it is removed).
    """
    path = Path(bag_dir)
    original, wal = the_mcap_file(path), path / WAL_NAME
    if _bag_is_complete(path):
        wal.unlink(missing_ok=True)
        return RecoveryReport(path, bag_info(path).counts, None, truncated=False)
    try:
        scan = scan_data_section(original, strict=False, keep_messages=True)
    except DamagedMcap as exc:
        raise BagError(f"{original} cannot be recovered: {exc.reason}") from None
    wal_catalogue, records = read_write_ahead_log(wal)
    if not scan.channels and not wal_catalogue:
        reasons = "; ".join(scan.dropped) or "no chunk was completed"
        raise BagError(f"{original} cannot be recovered: it declares no channel and there is "
                       f"no write-ahead log ({reasons})")
    catalogue = _catalogue(scan, wal_catalogue, original)
    messages = scan.messages
    _add_logged_messages(messages, catalogue, records, wal, original)
    kept = original.with_name(original.name + ".truncated")
    counts = _rewrite(path, original, kept, catalogue, messages)
    return RecoveryReport(path, counts, kept, truncated=True, dropped=scan.dropped)


def _rewrite(path: Path, original: Path, kept: Path, catalogue: dict, messages: list) -> dict:
    """Write ``messages`` into a fresh bag staged beside ``path``, then put it in the
    place of the damaged ``original`` (moved to ``kept``) and of the write-ahead
    log (kept as ``.recovered``). Returns the counts."""
    from rosbags.rosbag2.metadata import parse_qos

    wal = path / WAL_NAME
    topics = {topic: msgtype for topic, msgtype, _ in catalogue.values()}
    qos = {topic: parse_qos(offered) if offered else [] for topic, _, offered in catalogue.values()}
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=f".{path.name}.recover-") as tmp:
        staged = Path(tmp) / path.name
        writer = BagWriter(staged, topics, qos=qos)
        for log_time, channel_id, data in sorted(messages, key=lambda m: m[0]):
            writer.write(catalogue[channel_id][0], log_time, data)
        counts = dict(writer.counts)
        writer.close()
        original.replace(kept)
        if wal.is_file():
            wal.replace(path / (WAL_NAME + ".recovered"))
        # the rebuilt file is <dir>.mcap (rosbags' name), metadata.yaml lists it
        for produced in staged.iterdir():
            shutil.move(str(produced), str(path / produced.name))
    return counts
