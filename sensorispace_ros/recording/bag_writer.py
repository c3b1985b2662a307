"""Where a bag gets written: ``BagWriter`` (rosbag2 v9, MCAP with zstd chunks and
CRCs, raw CDR) and its write-ahead log.

``BagWriter`` writes through ``recording.bag_storage.Rosbag2Writer``
(metadata.yaml by rosbags, the .mcap by the official mcap writer; the format:
recording.bag_format).

Crash safety (kill -9): MCAP messages live in chunks. ``BagWriter`` closes the
open chunk once it holds ``chunk_bytes`` (1 MiB uncompressed) or is
``chunk_interval_s`` old (checked on every write and by ``flush_if_due``,
which the recorder calls from a timer) and hands every closed chunk, compressed
and with its CRC, to the operating system. Without more, a process killed with
-9 loses the open chunk: at most ``chunk_interval_s`` or 1 MiB of messages.

Write-ahead log (``write_ahead=True``, the recorder's default): every message
of the open chunk is also appended to ``<bag>/recording.wal`` by ``commit()``
(one unbuffered ``os.write`` per batch; the recorder commits after each
subscription callback), and the log starts again whenever a chunk reaches the
OS. Each log starts with the bag's catalogue (topic -> channel id, type,
offered QoS), so that its records can be read even before a chunk holding the
MCAP schemas and channels exists. A kill -9 then loses nothing the recorder
has committed: the page cache keeps both files (no fsync: a power cut may
lose more; a killed process does not). ``read_write_ahead_log`` reads it back
for recording.bag_recovery.
"""
from __future__ import annotations

import json
import os
import struct
import time
from collections import Counter
from pathlib import Path
from typing import Mapping

from sensorispace_ros.recording.bag_format import BagError, one_line, typestore

DEFAULT_CHUNK_INTERVAL_S = 1.0
DEFAULT_CHUNK_BYTES = 1 << 20
WAL_NAME = "recording.wal"
# one log record: topic length (u16), log time (i64 ns), data length (u32), then
# the topic name and the CDR bytes; a record with an empty topic is the catalogue (JSON)
WAL_HEADER = struct.Struct("<HqI")


def _qos_profile(spec: Mapping[str, object] | list | None):
    """rosbags Qos for metadata.yaml from a topics.yaml qos entry (None -> empty list)."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    if not spec:
        return []
    if isinstance(spec, list):  # already rosbags Qos profiles (e.g. read back from a bag)
        return spec
    history = QosHistory[str(spec.get("history", "keep_all")).upper()]
    unset = QosTime(0, 0)  # rosbag2's "default" deadline/lifespan/lease
    return [
        Qos(
            history,
            int(spec.get("depth", 0)),
            QosReliability[str(spec.get("reliability", "reliable")).upper()],
            QosDurability[str(spec.get("durability", "volatile")).upper()],
            unset,
            unset,
            QosLiveliness.AUTOMATIC,
            unset,
            False,
        )
    ]


class BagWriter:
    """Write raw CDR messages into a new rosbag2 v9 MCAP bag directory.

    ``topics`` maps topic name -> ROS type ("sensor_msgs/msg/PointCloud2");
    ``qos`` optionally maps topic name -> topics.yaml qos dict (stored as the
    offered QoS in metadata.yaml so ``ros2 bag play`` re-offers it).
    """

    def __init__(
        self,
        bag_dir: str | os.PathLike,
        topics: Mapping[str, str],
        qos: Mapping[str, Mapping[str, object]] | None = None,
        chunk_interval_s: float = DEFAULT_CHUNK_INTERVAL_S,
        write_ahead: bool = False,
        chunk_bytes: int = DEFAULT_CHUNK_BYTES,
    ) -> None:
        if not chunk_interval_s > 0:
            raise ValueError(f"chunk_interval_s must be > 0, got {chunk_interval_s!r}")
        if not chunk_bytes > 0:
            raise ValueError(f"chunk_bytes must be > 0, got {chunk_bytes!r}")
        if not topics:
            raise ValueError("topics must name at least one topic")
        self.path = Path(bag_dir)
        self.chunk_interval_s = float(chunk_interval_s)
        self.chunk_bytes = int(chunk_bytes)
        self._writer = self._open_writer()
        self._storage = self._writer.storage
        self._connections = self._add_connections(topics, qos or {})
        self.counts: Counter[str] = Counter({name: 0 for name in topics})
        self._chunk_opened = time.monotonic()
        self._wal_fd: int | None = None
        self._wal_pending: list[bytes] = []
        self._wal_catalogue = b""
        if write_ahead:
            self._wal_fd = os.open(self.path / WAL_NAME,
                                   os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND, 0o644)
            catalogue = {topic: {"channel_id": self._connections[topic].id, **entry}
                         for topic, entry in self._storage.catalogue.items()}
            data = json.dumps(catalogue).encode()
            self._wal_catalogue = WAL_HEADER.pack(0, 0, len(data)) + data
            os.write(self._wal_fd, self._wal_catalogue)

    def _open_writer(self):
        from rosbags.rosbag2.errors import WriterError

        from sensorispace_ros.recording.bag_storage import Rosbag2Writer

        try:
            writer = Rosbag2Writer(self.path)
            writer.open()
        except (WriterError, OSError) as exc:
            raise BagError(f"cannot create bag {self.path}: {one_line(exc)}") from None
        return writer

    def _add_connections(self, topics: Mapping[str, str], qos: Mapping) -> dict:
        store = typestore()
        connections = {}
        try:
            for name, msgtype in topics.items():
                if msgtype not in store.types:
                    raise BagError(f"topic {name}: unknown message type {msgtype!r}")
                connections[name] = self._writer.add_connection(
                    name,
                    msgtype,
                    typestore=store,
                    offered_qos_profiles=_qos_profile(qos.get(name)),
                )
        except Exception:
            self._writer.abort()
            raise
        return connections

    @property
    def closed(self) -> bool:
        return self._writer.storage is None

    @property
    def open_chunk_messages(self) -> int:
        """Messages of the chunk being filled (0: every message is on disk)."""
        return self._storage.open_chunk_messages

    def write(self, topic: str, timestamp_ns: int, cdr: bytes | memoryview) -> None:
        connection = self._connections.get(topic)
        if connection is None:
            raise BagError(f"topic {topic} was not declared when the bag was opened")
        if self.closed:
            raise BagError(f"bag {self.path} is closed")
        data = bytes(cdr)
        self._writer.write(connection, int(timestamp_ns), data)
        self.counts[topic] += 1
        if self._wal_fd is not None:
            name = topic.encode()
            self._wal_pending.append(WAL_HEADER.pack(len(name), int(timestamp_ns), len(data))
                                     + name + data)
        if self._storage.open_chunk_bytes >= self.chunk_bytes:
            self.flush_chunk()
        else:
            self.flush_if_due()

    def commit(self) -> None:
        """Append the messages written since the last commit to the write-ahead log
        (one unbuffered write; survives kill -9). No-op without ``write_ahead``."""
        if self._wal_fd is not None and self._wal_pending:
            os.write(self._wal_fd, b"".join(self._wal_pending))
            self._wal_pending.clear()

    def _empty_wal(self) -> None:
        """Every message written so far is in a chunk the OS holds: the log restarts
        (with the catalogue)."""
        if self._wal_fd is not None:
            self._wal_pending.clear()
            os.ftruncate(self._wal_fd, 0)
            os.write(self._wal_fd, self._wal_catalogue)

    def flush_if_due(self) -> bool:
        """Close the open chunk if it is older than ``chunk_interval_s``."""
        if self.closed or time.monotonic() - self._chunk_opened < self.chunk_interval_s:
            return False
        self.flush_chunk()
        return True

    def flush_chunk(self) -> None:
        """Close the open MCAP chunk (if it holds anything) and write it to the OS."""
        self._chunk_opened = time.monotonic()
        if not self.closed and self._storage.flush_chunk():
            self._empty_wal()

    def close(self) -> None:
        """Write the last chunk, the summary (with Statistics) and metadata.yaml; idempotent."""
        if self.closed:
            return
        self._storage.flush_chunk()
        self._writer.close()
        if self._wal_fd is not None:
            os.close(self._wal_fd)
            self._wal_fd = None
            (self.path / WAL_NAME).unlink(missing_ok=True)

    def __enter__(self) -> "BagWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()


def read_write_ahead_log(path: Path) -> tuple[dict, list[tuple[str, int, bytes]]]:
    """The catalogue (topic -> channel_id, type, offered_qos_profiles) and the
    (topic, log time, data) of every complete record of a write-ahead log."""
    if not path.is_file():
        return {}, []
    raw = path.read_bytes()
    catalogue, records, offset = {}, [], 0
    while offset + WAL_HEADER.size <= len(raw):
        name_len, log_time, data_len = WAL_HEADER.unpack_from(raw, offset)
        start = offset + WAL_HEADER.size
        end = start + name_len + data_len
        if end > len(raw):
            break                     # cut short by the kill
        if name_len == 0:
            catalogue = json.loads(raw[start:end])
        else:
            records.append((raw[start:start + name_len].decode(), log_time,
                            raw[start + name_len:end]))
        offset = end
    return catalogue, records
