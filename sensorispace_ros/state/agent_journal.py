"""What the agent node persists to survive ``kill -9``: a snapshot
plus a journal, pure Python + numpy (no rclpy; tested without ROS).

``<dir>/agent.snapshot`` is a pickled dict written atomically (tmp file +
``os.replace``) at an event boundary: the NaiveAgent's state and the node's
counters. ``<dir>/agent.journal`` holds, since that snapshot, every input the
agent consumed, appended with one unbuffered ``os.write`` per record (the
page cache keeps it through a kill -9; no fsync: a power cut is out of
scope). Replaying the journal through the deterministic agent rebuilds the
state it had when it died.

Record layout (little-endian): ``kind`` (1 byte: ``C``/``E`` passive
sensation of change/end ``number``, ``A`` body answer to command ``number``,
``S`` change ``number`` settled), ``number`` int64, ``check`` uint32 (for
``A`` the crc32 of the command's motor states, so a replay that issues
another command is caught), ``rows``, ``cols`` uint32, ``rows*cols``
float64, then the crc32 of everything before (written with one ``os.writev``). A kill during a write leaves a
short or unchecked last record: it is ignored (and cut off before the next
append), never fatal.
"""
from __future__ import annotations

import os
import pickle
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sensorispace_ros.protocol import JOURNAL_FILE, SNAPSHOT_FILE  # noqa: F401 (the state's files)

SNAPSHOT_FORMAT = 1

_HEAD = struct.Struct("<cqIII")
_CRC = struct.Struct("<I")
PASSIVE_KINDS = {"change": b"C", "end": b"E"}
_PASSIVE_NAMES = {code: name for name, code in PASSIVE_KINDS.items()}
ANSWER, SETTLED = b"A", b"S"


class CheckpointError(RuntimeError):
    """A snapshot or journal that cannot be used; the message names the file."""


def command_check(motor_states: np.ndarray) -> int:
    """crc32 of a command's motor states (float64, C order)."""
    return zlib.crc32(np.ascontiguousarray(motor_states, dtype="<f8").tobytes())


def encode_record(kind: bytes, number: int, rows: np.ndarray | None = None,
                  check: int = 0) -> list:
    """The record as a list of byte strings (header, data, crc) for ``os.writev``."""
    if rows is None:
        head, data = _HEAD.pack(kind, number, check, 0, 0), b""
    else:
        rows = np.asarray(rows, dtype="<f8")
        head = _HEAD.pack(kind, number, check, *rows.shape)
        data = rows.tobytes()
    return [head, data, _CRC.pack(zlib.crc32(data, zlib.crc32(head)))]


@dataclass
class JournalContent:
    """The records of a journal, in the order the agent consumed them."""

    passives: list = field(default_factory=list)     # (kind, number, row (S,))
    answers: dict = field(default_factory=dict)      # command number -> (check, rows)
    settled: list = field(default_factory=list)      # change numbers
    valid_bytes: int = 0                             # length of the intact prefix
    torn_bytes: int = 0                              # ignored tail (a kill mid-write)


def read_journal(path: str | Path) -> JournalContent:
    """Every intact record of ``path`` (missing file: empty). A short or
    unchecked LAST record is a write cut by a kill: ignored. A bad record
    followed by intact ones is corruption: CheckpointError naming the file."""
    content = JournalContent()
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        return content
    except OSError as exc:
        raise CheckpointError(f"{path}: cannot read the agent journal: {exc}") from exc
    offset = 0
    while offset < len(data):
        record = _parse_record(data, offset)
        if record is None:
            if _has_intact_record_after(data, offset):
                raise CheckpointError(f"{path}: corrupt agent journal record at byte {offset}")
            content.torn_bytes = len(data) - offset
            break
        kind, number, check, rows, offset = record
        if kind in _PASSIVE_NAMES:
            content.passives.append((_PASSIVE_NAMES[kind], number, rows[0]))
        elif kind == ANSWER:
            content.answers[number] = (check, rows)
        else:
            content.settled.append(number)
    content.valid_bytes = offset
    return content


def _parse_record(data: bytes, offset: int):
    if len(data) - offset < _HEAD.size + _CRC.size:
        return None
    kind, number, check, n_rows, n_cols = _HEAD.unpack_from(data, offset)
    if kind not in _PASSIVE_NAMES and kind not in (ANSWER, SETTLED):
        return None
    end = offset + _HEAD.size + 8 * n_rows * n_cols
    if end + _CRC.size > len(data):
        return None
    if _CRC.unpack_from(data, end)[0] != zlib.crc32(data[offset:end]):
        return None
    rows = np.frombuffer(data, dtype="<f8", count=n_rows * n_cols,
                         offset=offset + _HEAD.size).reshape(n_rows, n_cols).copy()
    if kind in _PASSIVE_NAMES and n_rows != 1:
        return None
    return kind, int(number), int(check), rows, end + _CRC.size


def _has_intact_record_after(data: bytes, offset: int) -> bool:
    # A torn tail is at most one record; an intact record further on means the
    # damage is inside the file. Only record starts are candidates (kind byte).
    for start in range(offset + 1, len(data)):
        if data[start:start + 1] in (b"C", b"E", ANSWER, SETTLED) \
                and _parse_record(data, start) is not None:
            return True
    return False


class AgentJournal:
    """Append-only journal; ``open`` cuts a torn tail off first."""

    def __init__(self, path: str | Path, valid_bytes: int = 0):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT, 0o644)
        os.ftruncate(self._fd, valid_bytes)
        os.lseek(self._fd, valid_bytes, os.SEEK_SET)
        self.records = 0
        self.bytes = valid_bytes

    def _append(self, record: list) -> None:
        # One system call, no Python-side buffer: what it wrote is in the page cache.
        written = os.writev(self._fd, record)
        size = sum(len(part) for part in record)
        if written != size:
            raise CheckpointError(f"{self.path}: short write ({written} of {size} bytes)")
        self.records += 1
        self.bytes += written

    def passive(self, kind: str, number: int, row: np.ndarray) -> None:
        self._append(encode_record(PASSIVE_KINDS[kind], int(number), np.reshape(row, (1, -1))))

    def answer(self, number: int, check: int, rows: np.ndarray) -> None:
        self._append(encode_record(ANSWER, int(number), np.reshape(rows, (len(rows), -1)),
                                   int(check)))

    def settled(self, number: int) -> None:
        self._append(encode_record(SETTLED, int(number)))

    def truncate(self) -> None:
        os.ftruncate(self._fd, 0)
        os.lseek(self._fd, 0, os.SEEK_SET)
        self.bytes = 0

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


def write_snapshot(path: str | Path, state: dict) -> int:
    """Pickle ``state`` to ``path`` atomically; returns its size in bytes."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = pickle.dumps({"format": SNAPSHOT_FORMAT, **state}, protocol=pickle.HIGHEST_PROTOCOL)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as handle:
        handle.write(data)
    os.replace(tmp, path)
    return len(data)


def read_snapshot(path: str | Path) -> dict | None:
    """The snapshot at ``path``; None when there is none; CheckpointError
    naming the file when it cannot be read as one."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise CheckpointError(f"{path}: cannot read the agent snapshot: {exc}") from exc
    try:
        state = pickle.loads(data)
    except Exception as exc:       # pickle raises many types on damaged input
        raise CheckpointError(f"{path}: corrupt agent snapshot "
                              f"({type(exc).__name__}: {exc})") from exc
    if not isinstance(state, dict) or state.get("format") != SNAPSHOT_FORMAT:
        raise CheckpointError(f"{path}: not an agent snapshot of format {SNAPSHOT_FORMAT}")
    return state


# The agent node's own counters in a snapshot (beside NaiveAgent.state()):
# on the node, and on its BodyOverTopics.
NODE_FIELDS = ("last_passive", "last_settled", "n_povs", "n_rows", "run_over")
BODY_FIELDS = ("requests", "retransmits", "round_trip_s")


def node_snapshot(node, body) -> dict:
    """The node's and its body link's counters and queued passive sensations."""
    return {**{name: getattr(node, name) for name in NODE_FIELDS},
            **{name: getattr(body, name) for name in BODY_FIELDS},
            "passive": list(node.passive)}


def restore_node(saved: dict, node, body) -> None:
    """``node_snapshot``'s counters back on ``node`` and ``body`` (KeyError if one is missing)."""
    values = {name: saved[name] for name in NODE_FIELDS + BODY_FIELDS + ("passive",)}
    for name in NODE_FIELDS:
        setattr(node, name, values[name])
    for name in BODY_FIELDS:
        setattr(body, name, values[name])
    node.passive.extend(values["passive"])
