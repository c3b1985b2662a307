"""rosbag2 (MCAP) recording, reading and crash recovery, without rclpy.

Bags are written by ``rosbags.rosbag2.Writer(version=9, storage_plugin=MCAP)``:
a directory holding ``metadata.yaml`` (rosbag2 version 9, as Jazzy writes) and
one ``<dir>.mcap`` file with profile ``ros2``, ``ros2msg`` schemas, ``cdr``
messages and a summary with Statistics. Messages are stored as the exact CDR
bytes a ``raw=True`` subscription delivers (``rclpy.serialization.
serialize_message`` appends 8-12 garbage bytes on Jazzy that rosbags rejects).

Crash safety (kill -9): MCAP messages live in chunks. rosbags closes a chunk
when it exceeds 1 MiB; ``BagWriter`` additionally closes the open chunk once it
is ``chunk_interval_s`` old (default 1 s, checked on every write and by
``flush_if_due``, which the recorder calls from a timer) and hands every
closed chunk to the operating system (``flush``). Without more, a process
killed with -9 loses the open chunk: <= 1 s or <= 1 MiB of messages.

Write-ahead log (``write_ahead=True``, the recorder's default, issue #7): every
message of the open chunk is also appended to ``<bag>/recording.wal`` by
``commit()`` (one unbuffered ``os.write`` per batch; the recorder commits after
each subscription callback), and the log is emptied whenever a chunk reaches
the OS. A kill -9 then loses nothing the recorder has committed: the page cache
keeps both files. (No fsync: a power cut may lose more; a killed process does
not.) ``recover_bag`` rebuilds a normal bag from every complete chunk plus the
log's complete records (a record also found in the last chunk, killed between
the chunk flush and the log truncation, is kept once).

The session configuration travels inside the bag as the first message of
``SESSION_CONFIG_TOPIC`` (std_msgs/msg/String holding the ROS params-file
YAML), so ``sensorispace analyze`` needs nothing but the bag.
"""

from __future__ import annotations

import os
import shutil
import struct
import tempfile
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Mapping


SESSION_CONFIG_TOPIC = "/session/config"
SESSION_CONFIG_TYPE = "std_msgs/msg/String"
DEFAULT_CHUNK_INTERVAL_S = 1.0
WAL_NAME = "recording.wal"
# one log record: topic length (u16), log time (i64 ns), data length (u32), then
# the topic name and the CDR bytes
_WAL_HEADER = struct.Struct("<HqI")


class BagError(Exception):
    """A bag that cannot be written, read or recovered; the message is one line."""


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def _typestore():
    from rosbags.typesys import Stores, get_typestore

    # Jazzy's store: its RIHS01 hashes equal the ones the Jazzy wheels announce.
    return get_typestore(Stores.ROS2_JAZZY)


def _qos_profile(spec: Mapping[str, object] | None):
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
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.rosbag2.errors import WriterError

        if not chunk_interval_s > 0:
            raise ValueError(f"chunk_interval_s must be > 0, got {chunk_interval_s!r}")
        if not topics:
            raise ValueError("topics must name at least one topic")
        self.path = Path(bag_dir)
        self.chunk_interval_s = float(chunk_interval_s)
        store = _typestore()
        try:
            self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
            self._writer.open()
        except (WriterError, OSError) as exc:
            raise BagError(f"cannot create bag {self.path}: {_one_line(exc)}") from None
        if not hasattr(self._writer.storage, "close_chunk"):
            self._writer.abort()
            raise BagError("this rosbags version has no McapWriter.close_chunk "
                           "(BagWriter's crash-safe chunking needs rosbags 0.11, see requirements.lock)")
        self._connections = {}
        try:
            for name, msgtype in topics.items():
                if msgtype not in store.types:
                    raise BagError(f"topic {name}: unknown message type {msgtype!r}")
                self._connections[name] = self._writer.add_connection(
                    name,
                    msgtype,
                    typestore=store,
                    offered_qos_profiles=_qos_profile((qos or {}).get(name)),
                )
        except Exception:
            self._writer.abort()
            raise
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
            self._wal_pending.append(_WAL_HEADER.pack(len(name), int(timestamp_ns), len(data))
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


# ----------------------------------------------------------------- reading


@dataclass(frozen=True)
class BagInfo:
    path: Path
    topics: dict[str, str]  # name -> type
    counts: dict[str, int]  # name -> messages, from metadata.yaml


def _mcap_files(bag_dir: Path) -> list[Path]:
    return sorted(p for p in bag_dir.glob("*.mcap"))


def _open_reader(bag_dir: str | os.PathLike):
    from rosbags.rosbag2 import Reader

    path = Path(bag_dir)
    if not path.exists():
        raise BagError(f"bag {path} does not exist")
    if not path.is_dir():
        raise BagError(f"bag {path} is not a directory (expected a rosbag2 bag directory)")
    if not (path / "metadata.yaml").is_file():
        hint = (
            f"; run `sensorispace bag recover {path}`" if _mcap_files(path) else ""
        )
        raise BagError(f"bag {path} has no metadata.yaml (not closed cleanly?){hint}")
    reader = Reader(path)
    try:
        reader.open()
    except Exception as exc:  # rosbags raises ReaderError, struct.error, ...
        raise BagError(f"bag {path} is unreadable: {_one_line(exc)}") from None
    return reader


def bag_info(bag_dir: str | os.PathLike) -> BagInfo:
    reader = _open_reader(bag_dir)
    try:
        topics = {name: info.msgtype for name, info in reader.topics.items()}
        counts = {name: info.msgcount for name, info in reader.topics.items()}
    finally:
        reader.close()
    return BagInfo(Path(bag_dir), topics, counts)


def check_contract(bag_dir: str | os.PathLike, contract_types: Mapping[str, str]) -> BagInfo:
    """BagError unless every contract topic present in the bag has the contract's type
    and the bag holds at least one contract topic (otherwise it is another schema)."""
    info = bag_info(bag_dir)
    shared = [name for name in info.topics if name in contract_types]
    if not shared:
        raise BagError(
            f"bag {info.path} is of another schema: none of its topics "
            f"({', '.join(sorted(info.topics)) or 'none'}) is in the topic contract"
        )
    for name in shared:
        if info.topics[name] != contract_types[name]:
            raise BagError(
                f"bag {info.path} is of another schema: topic {name} has type "
                f"{info.topics[name]}, the contract says {contract_types[name]}"
            )
    return info


def read_bag(
    bag_dir: str | os.PathLike, topics: list[str] | None = None
) -> Iterator[tuple[str, str, int, bytes]]:
    """Yield (topic, type, timestamp_ns, cdr_bytes) in timestamp order."""
    reader = _open_reader(bag_dir)
    try:
        connections = reader.connections
        if topics is not None:
            missing = sorted(set(topics) - {c.topic for c in connections})
            if missing:
                raise BagError(f"bag {bag_dir} has no topic {', '.join(missing)}")
            connections = [c for c in connections if c.topic in set(topics)]
        try:
            for connection, timestamp, data in reader.messages(connections=connections):
                yield connection.topic, connection.msgtype, timestamp, bytes(data)
        except BagError:
            raise
        except Exception as exc:
            raise BagError(f"bag {bag_dir} is unreadable: {_one_line(exc)}") from None
    finally:
        reader.close()


def read_bag_messages(
    bag_dir: str | os.PathLike, topics: list[str] | None = None
) -> Iterator[tuple[str, str, int, object]]:
    """Like read_bag but yields rclpy message objects (imports rclpy lazily)."""
    from rclpy.serialization import deserialize_message

    classes: dict[str, type] = {}
    for topic, msgtype, timestamp, cdr in read_bag(bag_dir, topics):
        cls = classes.get(msgtype) or classes.setdefault(msgtype, message_class(msgtype))
        try:
            message = deserialize_message(cdr, cls)
        except Exception as exc:
            raise BagError(
                f"bag {bag_dir}: a {msgtype} message on {topic} does not deserialise: "
                f"{_one_line(exc)}"
            ) from None
        yield topic, msgtype, timestamp, message


def message_class(type_name: str) -> type:
    """The generated Python class of "pkg/msg/Name" (imports the ROS package lazily)."""
    import importlib

    package, _, name = type_name.split("/")
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError):
        raise BagError(f"message type {type_name} is not installed") from None


def read_session_config(bag_dir: str | os.PathLike) -> str:
    """The params-file YAML the run was started with (first /session/config message)."""
    info = bag_info(bag_dir)
    if SESSION_CONFIG_TOPIC not in info.topics or not info.counts.get(SESSION_CONFIG_TOPIC):
        raise BagError(f"bag {info.path} holds no {SESSION_CONFIG_TOPIC} message (config of the run)")
    store = _typestore()
    for _, msgtype, _, cdr in read_bag(bag_dir, [SESSION_CONFIG_TOPIC]):
        return store.deserialize_cdr(cdr, msgtype).data
    raise BagError(f"bag {info.path} holds no {SESSION_CONFIG_TOPIC} message")


def session_config_cdr(params_yaml: str) -> bytes:
    """CDR bytes of a std_msgs/msg/String holding ``params_yaml``."""
    store = _typestore()
    string_cls = store.types[SESSION_CONFIG_TYPE]
    return bytes(store.serialize_cdr(string_cls(data=params_yaml), SESSION_CONFIG_TYPE))


def copy_bag(source: str | os.PathLike, target: str | os.PathLike,
             topics: list[str] | None = None) -> dict[str, int]:
    """Copy ``topics`` (default all) of a bag, bytes and timestamps unchanged, into a new
    bag (e.g. a small sample without the bulky probing streams). Returns the counts."""
    from rosbags.rosbag2 import Reader

    info = bag_info(source)
    chosen = list(info.topics) if topics is None else list(topics)
    missing = sorted(set(chosen) - set(info.topics))
    if missing:
        raise BagError(f"bag {source} has no topic {', '.join(missing)}")
    with Reader(Path(source)) as reader:
        qos = {c.topic: list(c.ext.offered_qos_profiles) for c in reader.connections}
    with BagWriter(target, {name: info.topics[name] for name in chosen},
                   qos={name: qos.get(name, []) for name in chosen}) as writer:
        for topic, _, timestamp, cdr in read_bag(source, chosen):
            writer.write(topic, timestamp, cdr)
        return dict(writer.counts)


def merge_bags(sources: list, target: str | os.PathLike) -> dict[str, int]:
    """One bag holding every message of ``sources`` in timestamp order (e.g. the parts
    of a recording interrupted by a recorder restart). Returns the counts."""
    import heapq

    infos = [bag_info(source) for source in sources]
    topics: dict[str, str] = {}
    for info in infos:
        for name, msgtype in info.topics.items():
            if topics.setdefault(name, msgtype) != msgtype:
                raise BagError(f"cannot merge: topic {name} is {topics[name]} in one bag "
                               f"and {msgtype} in {info.path}")
    streams = [((t, topic, cdr) for topic, _, t, cdr in read_bag(s)) for s in sources]
    with BagWriter(target, topics) as writer:
        for timestamp, topic, cdr in heapq.merge(*streams, key=lambda m: m[0]):
            writer.write(topic, timestamp, cdr)
        return dict(writer.counts)


# ---------------------------------------------------------------- recovery


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
        reader = _open_reader(bag_dir)
    except BagError:
        return False
    reader.close()
    files = _mcap_files(bag_dir)
    return all(_mcap_has_summary(p) for p in files)


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
    from mcap.exceptions import McapError
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
                    f"({_one_line(exc)})"
                ) from None
    return schemas, channels, messages


def _read_wal(path: Path) -> list[tuple[str, int, bytes]]:
    """(topic, log time, data) of every complete record of a write-ahead log."""
    if not path.is_file():
        return []
    raw = path.read_bytes()
    records, offset = [], 0
    while offset + _WAL_HEADER.size <= len(raw):
        name_len, log_time, data_len = _WAL_HEADER.unpack_from(raw, offset)
        start = offset + _WAL_HEADER.size
        end = start + name_len + data_len
        if end > len(raw):
            break                     # cut short by the kill
        records.append((raw[start:start + name_len].decode(), log_time,
                        raw[start + name_len:end]))
        offset = end
    return records


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
    from rosbags.rosbag2.metadata import parse_qos

    path = Path(bag_dir)
    if not path.is_dir():
        raise BagError(f"bag {path} does not exist or is not a directory")
    files = _mcap_files(path)
    if len(files) != 1:
        raise BagError(f"bag {path} must hold exactly one .mcap file, found {len(files)}")
    original = files[0]
    wal = path / WAL_NAME
    if _bag_is_complete(path):
        wal.unlink(missing_ok=True)
        info = bag_info(path)
        return RecoveryReport(path, info.counts, None, truncated=False)
    try:
        schemas, channels, messages = _scan_truncated_mcap(original)
    except McapError as exc:
        raise BagError(f"{original} cannot be recovered: {_one_line(exc)}") from None
    channel_of_topic = {channel.topic: cid for cid, channel in channels.items()}
    in_chunks = set(messages)
    for topic, log_time, data in _read_wal(wal):
        cid = channel_of_topic.get(topic)
        if cid is None:
            raise BagError(f"{wal} names topic {topic}, which {original} does not declare")
        if (log_time, cid, data) not in in_chunks:
            messages.append((log_time, cid, data))
    store = _typestore()
    topics, qos = {}, {}
    for channel in channels.values():
        schema = schemas.get(channel.schema_id)
        if schema is None or channel.message_encoding != "cdr":
            raise BagError(f"{original} is of another schema: channel {channel.topic} is not ros2 cdr")
        if schema.name not in store.types:
            raise BagError(f"{original} is of another schema: unknown type {schema.name}")
        topics[channel.topic] = schema.name
        offered = channel.metadata.get("offered_qos_profiles")
        qos[channel.topic] = parse_qos(offered) if offered else []

    with tempfile.TemporaryDirectory(dir=path.parent, prefix=f".{path.name}.recover-") as tmp:
        staged = Path(tmp) / path.name
        writer = BagWriter(staged, topics, qos=qos)
        id_to_topic = {cid: ch.topic for cid, ch in channels.items()}
        for log_time, channel_id, data in sorted(messages, key=lambda m: m[0]):
            writer.write(id_to_topic[channel_id], log_time, data)
        counts = dict(writer.counts)
        writer.close()
        kept = original.with_name(original.name + ".truncated")
        original.replace(kept)
        if wal.is_file():
            wal.replace(path / (WAL_NAME + ".recovered"))
        # the rebuilt file is <dir>.mcap (rosbags' name), metadata.yaml lists it
        for produced in staged.iterdir():
            shutil.move(str(produced), str(path / produced.name))
    return RecoveryReport(path, counts, kept, truncated=True)
