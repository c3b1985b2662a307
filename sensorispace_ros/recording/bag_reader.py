"""Reading a bag: its topics and counts, its raw CDR or decoded messages in
timestamp order, its session configuration, and the check that it follows the
topic contract. Opening a bag checks its MCAP summary CRC; rosbags checks each
chunk's CRC as it decompresses it (every CRC: ``bag verify``). Every problem is
a one-line ``BagError``; no rclpy (messages are decoded by rosbags)."""
from __future__ import annotations

import contextlib
import importlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Mapping

from sensorispace_ros.recording.bag_format import (
    SESSION_CONFIG_TOPIC,
    BagError,
    one_line,
    typestore,
)
from sensorispace_ros.recording.bag_integrity import summary_section


@dataclass(frozen=True)
class BagInfo:
    path: Path
    topics: dict[str, str]  # name -> type
    counts: dict[str, int]  # name -> messages, from metadata.yaml


def mcap_files(bag_dir: Path) -> list[Path]:
    return sorted(p for p in bag_dir.glob("*.mcap"))


def the_mcap_file(bag_dir: str | os.PathLike) -> Path:
    """The one ``.mcap`` file of the bag directory ``bag_dir``, or a BagError."""
    path = Path(bag_dir)
    if not path.is_dir():
        raise BagError(f"bag {path} does not exist or is not a directory")
    files = mcap_files(path)
    if len(files) != 1:
        raise BagError(f"bag {path} must hold exactly one .mcap file, found {len(files)}")
    return files[0]


def open_reader(bag_dir: str | os.PathLike):
    """An open ``rosbags.rosbag2.Reader`` of a closed bag, or a BagError saying why not."""
    from rosbags.rosbag2 import Reader

    path = Path(bag_dir)
    if not path.exists():
        raise BagError(f"bag {path} does not exist")
    if not path.is_dir():
        raise BagError(f"bag {path} is not a directory (expected a rosbag2 bag directory)")
    if not (path / "metadata.yaml").is_file():
        hint = (
            f"; run `sensorispace bag recover {path}`" if mcap_files(path) else ""
        )
        raise BagError(f"bag {path} has no metadata.yaml (not closed cleanly?){hint}")
    try:
        for mcap in mcap_files(path):
            summary_section(mcap, require_crc=False)  # rosbags does not check the summary CRC
    except BagError as exc:
        raise BagError(f"bag {path} is unreadable: {exc}") from None
    reader = Reader(path)
    try:
        reader.open()
    except Exception as exc:  # rosbags raises ReaderError, struct.error, ...
        raise BagError(f"bag {path} is unreadable: {one_line(exc)}") from None
    return reader


# Bag directory -> BagInfo while an ``infos_kept`` block runs (None otherwise).
_KEPT_INFOS: dict | None = None


@contextlib.contextmanager
def infos_kept():
    """Within the block, ``bag_info`` opens each bag once: for a reader that
    asks many times about a bag nothing changes meanwhile (``analyze``)."""
    global _KEPT_INFOS
    outer, _KEPT_INFOS = _KEPT_INFOS, ({} if _KEPT_INFOS is None else _KEPT_INFOS)
    try:
        yield
    finally:
        _KEPT_INFOS = outer


def bag_info(bag_dir: str | os.PathLike) -> BagInfo:
    key = str(Path(bag_dir).resolve())
    if _KEPT_INFOS is not None and key in _KEPT_INFOS:
        return _KEPT_INFOS[key]
    reader = open_reader(bag_dir)
    try:
        topics = {name: info.msgtype for name, info in reader.topics.items()}
        counts = {name: info.msgcount for name, info in reader.topics.items()}
    finally:
        reader.close()
    info = BagInfo(Path(bag_dir), topics, counts)
    if _KEPT_INFOS is not None:
        _KEPT_INFOS[key] = info
    return info


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
    reader = open_reader(bag_dir)
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
            raise BagError(f"bag {bag_dir} is unreadable: {one_line(exc)}") from None
    finally:
        reader.close()


def read_bag_messages(
    bag_dir: str | os.PathLike, topics: list[str] | None = None
) -> Iterator[tuple[str, str, int, object]]:
    """Like read_bag but yields decoded messages: rosbags' classes of the Jazzy
    type store (the fields and names of the ROS messages; no rclpy)."""
    store = typestore()
    for topic, msgtype, timestamp, cdr in read_bag(bag_dir, topics):
        if msgtype not in store.types:
            raise BagError(f"message type {msgtype} is not installed")
        try:
            message = _decoded(store, cdr, msgtype)
        except Exception as exc:
            raise BagError(
                f"bag {bag_dir}: a {msgtype} message on {topic} does not deserialise: "
                f"{one_line(exc)}"
            ) from None
        yield topic, msgtype, timestamp, message


def _decoded(store, cdr: bytes, msgtype: str) -> object:
    """One CDR message as rosbags decodes it. Bytes after the message are
    padding (rclpy's serializer leaves some), ignored as rclpy ignores them."""
    if len(cdr) < 4 or cdr[:2] not in (b"\x00\x00", b"\x00\x01"):
        raise ValueError("not a CDR encapsulation")
    msgdef = store.get_msgdef(msgtype)
    decode = msgdef.deserialize_cdr_le if cdr[1] else msgdef.deserialize_cdr_be
    return decode(memoryview(cdr)[4:], 0, msgdef.cls, store)[0]


def message_class(type_name: str) -> type:
    """The generated Python class of "pkg/msg/Name" (imports the ROS package lazily)."""
    package, _, name = type_name.split("/")
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError):
        raise BagError(f"message type {type_name} is not installed") from None


def read_session_config(bag_dir: str | os.PathLike) -> str:
    """The params-file YAML the run was started with (first /session/config message)."""
    info = bag_info(bag_dir)
    if SESSION_CONFIG_TOPIC not in info.topics or not info.counts.get(SESSION_CONFIG_TOPIC):
        raise BagError(f"bag {info.path} holds no {SESSION_CONFIG_TOPIC} message "
                       "(config of the run)")
    store = typestore()
    for _, msgtype, _, cdr in read_bag(bag_dir, [SESSION_CONFIG_TOPIC]):
        return store.deserialize_cdr(cdr, msgtype).data
    raise BagError(f"bag {info.path} holds no {SESSION_CONFIG_TOPIC} message")
