"""Where a bag gets written: ``BagWriter`` (rosbag2 v9, MCAP, raw CDR) and its
write-ahead log.

``BagWriter`` writes through ``rosbags.rosbag2.Writer(version=9,
storage_plugin=MCAP)`` (the format: recording.bag_format).

Crash safety (kill -9): MCAP messages live in chunks. rosbags closes a chunk
when it exceeds 1 MiB; ``BagWriter`` also closes the open chunk once it is
``chunk_interval_s`` old (checked on every write and by ``flush_if_due``,
which the recorder calls from a timer) and hands every closed chunk to the
operating system (``flush``). Without more, a process killed with -9 loses
the open chunk: at most ``chunk_interval_s`` or 1 MiB of messages.

Write-ahead log (``write_ahead=True``, the recorder's default): every message
of the open chunk is also appended to ``<bag>/recording.wal`` by ``commit()``
(one unbuffered ``os.write`` per batch; the recorder commits after each
subscription callback), and the log is emptied whenever a chunk reaches the
OS. A kill -9 then loses nothing the recorder has committed: the page cache
keeps both files (no fsync: a power cut may lose more; a killed process does
not). ``read_write_ahead_log`` reads it back for recording.bag_recovery.
"""
from __future__ import annotations

import os
import struct
import time
from collections import Counter
from pathlib import Path
from typing import Mapping

from sensorispace_ros.recording.bag_format import BagError, one_line, typestore

DEFAULT_CHUNK_INTERVAL_S = 1.0
WAL_NAME = "recording.wal"
# one log record: topic length (u16), log time (i64 ns), data length (u32), then
# the topic name and the CDR bytes
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
    ) -> None:
        if not chunk_interval_s > 0:
            raise ValueError(f"chunk_interval_s must be > 0, got {chunk_interval_s!r}")
        if not topics:
            raise ValueError("topics must name at least one topic")
        self.path = Path(bag_dir)
        self.chunk_interval_s = float(chunk_interval_s)
        self._writer = self._open_writer()
        self._connections = self._add_connections(topics, qos or {})
        self.counts: Counter[str] = Counter({name: 0 for name in topics})
        self._chunk_opened = time.monotonic()
        self._chunks_flushed = 0
        self._wal_fd: int | None = None
        self._wal_pending: list[bytes] = []
        if write_ahead:
            self._wal_fd = os.open(self.path / WAL_NAME,
                                   os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND, 0o644)
        # The schema and channel records sit in the first chunk: close it now so
        # that even a bag killed in its first second can be recovered.
        self.flush_chunk()

    def _open_writer(self):
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.rosbag2.errors import WriterError

        try:
            writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
            writer.open()
        except (WriterError, OSError) as exc:
            raise BagError(f"cannot create bag {self.path}: {one_line(exc)}") from None
        if not hasattr(writer.storage, "close_chunk"):
            writer.abort()
            raise BagError("this rosbags version has no McapWriter.close_chunk "
                           "(BagWriter's crash-safe chunking needs rosbags 0.11, "
                           "see requirements.lock)")
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
        storage = self._writer.storage
        if len(storage.chunks) != self._chunks_flushed:
            # rosbags closed a full (1 MiB) chunk inside write(): hand it to the OS.
            storage.bio.flush()
            self._chunks_flushed = len(storage.chunks)
            self._chunk_opened = time.monotonic()
            self._empty_wal()
        else:
            self.flush_if_due()

    def commit(self) -> None:
        """Append the messages written since the last commit to the write-ahead log
        (one unbuffered write; survives kill -9). No-op without ``write_ahead``."""
        if self._wal_fd is not None and self._wal_pending:
            os.write(self._wal_fd, b"".join(self._wal_pending))
            self._wal_pending.clear()

    def _empty_wal(self) -> None:
        """Every message written so far is in a chunk the OS holds: the log restarts."""
        if self._wal_fd is not None:
            self._wal_pending.clear()
            os.ftruncate(self._wal_fd, 0)

    def flush_if_due(self) -> bool:
        """Close the open chunk if it is older than ``chunk_interval_s``."""
        if self.closed or time.monotonic() - self._chunk_opened < self.chunk_interval_s:
            return False
        self.flush_chunk()
        return True

    def flush_chunk(self) -> None:
        """Close the open MCAP chunk (if it holds anything) and write it to the OS."""
        storage = self._writer.storage
        if storage is None:
            return
        # rosbags' McapWriter has no public "close chunk" call; close_chunk is
        # what its own write() uses at 1 MiB (rosbags 0.11).
        if storage.chunk.bio.tell():
            storage.close_chunk()
        storage.bio.flush()
        self._chunks_flushed = len(storage.chunks)
        self._chunk_opened = time.monotonic()
        self._empty_wal()

    def close(self) -> None:
        """Write the summary (with Statistics) and metadata.yaml; idempotent."""
        if self.closed:
            return
        self._writer.close()
        if self._wal_fd is not None:
            os.close(self._wal_fd)
            self._wal_fd = None
            (self.path / WAL_NAME).unlink(missing_ok=True)

    def __enter__(self) -> "BagWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()


def read_write_ahead_log(path: Path) -> list[tuple[str, int, bytes]]:
    """(topic, log time, data) of every complete record of a write-ahead log."""
    if not path.is_file():
        return []
    raw = path.read_bytes()
    records, offset = [], 0
    while offset + WAL_HEADER.size <= len(raw):
        name_len, log_time, data_len = WAL_HEADER.unpack_from(raw, offset)
        start = offset + WAL_HEADER.size
        end = start + name_len + data_len
        if end > len(raw):
            break                     # cut short by the kill
        records.append((raw[start:start + name_len].decode(), log_time,
                        raw[start + name_len:end]))
        offset = end
    return records
