"""The checksums of a bag's MCAP file, read record by record (``bag verify``,
``bag recover``).

The MCAP format defines three CRC32s this project's writer fills in
(recording.bag_storage): each chunk's ``uncompressed_crc`` (of its records
before compression), the DataEnd record's ``data_section_crc`` (of every byte
from the leading magic to the DataEnd record) and the footer's
``summary_crc`` (of the summary section and the footer's first fields).
Message and chunk indexes carry no CRC: they are checked against the chunks
they index. A CRC of 0 means "not computed" in MCAP; here it is an error.

``scan_data_section`` walks the data section once: in ``strict`` mode (verify)
the first problem is a one-line BagError; otherwise (recovery) a chunk that
does not decompress or fails its CRC is dropped with a message and the walk
stops at the first record cut short. ``summary_section`` checks the summary
CRC (also on every open of a bag: recording.bag_reader).
"""
from __future__ import annotations

import os
import struct
import zlib
from collections import Counter
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import BinaryIO

from mcap.opcode import Opcode

from sensorispace_ros.recording.bag_format import BagError, one_line

MAGIC = b"\x89MCAP0\r\n"
RECORD_HEAD = struct.Struct("<BQ")       # opcode, body length
FOOTER_SIZE = RECORD_HEAD.size + 8 + 8 + 4   # summary_start, summary_offset_start, summary_crc


class DamagedMcap(BagError):
    """An MCAP whose bytes are not what its writer wrote: ``reason`` says where."""

    def __init__(self, path: Path, reason: str) -> None:
        super().__init__(f"{path}: {reason}")
        self.reason = reason


@dataclass
class ChunkSeen:
    offset: int
    counts: Counter = field(default_factory=Counter)   # channel id -> messages
    indexed: Counter = field(default_factory=Counter)  # channel id -> message index entries


@dataclass
class DataScan:
    """What the data section holds: schemas, channels, chunks, messages (if kept)."""

    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    chunks: list[ChunkSeen] = field(default_factory=list)
    counts: Counter = field(default_factory=Counter)      # channel id -> messages
    messages: list = field(default_factory=list)          # (log time, channel id, data)
    start: int | None = None                              # first and last log time
    end: int | None = None
    dropped: list[str] = field(default_factory=list)      # recovery: what was left out and why

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())


def chunk_records(chunk, where: str) -> list:
    """The records of a Chunk, after checking that it has a CRC and that it matches."""
    from mcap.stream_reader import CRCValidationError, breakup_chunk

    if chunk.uncompressed_crc == 0:
        raise BagError(f"{where} has no CRC")
    try:
        return breakup_chunk(chunk, validate_crc=True)
    except CRCValidationError:
        raise BagError(f"{where}: CRC mismatch (its contents changed after it was written)") from None
    except Exception as exc:   # zstd errors, an unknown compression, a record cut short
        raise BagError(f"{where} does not decompress: {one_line(exc)}") from None


class _Walker:
    """One pass over the records of the data section, with the running CRC."""

    def __init__(self, stream: BinaryIO, size: int, path: Path, strict: bool, keep_messages: bool):
        self.stream, self.size, self.path = stream, size, path
        self.strict, self.keep = strict, keep_messages
        self.scan = DataScan()
        self.crc = zlib.crc32(MAGIC)
        self.offset = len(MAGIC)
        self.chunk_number = 0

    def fail_or_stop(self, message: str, dropped: bool = True) -> bool:
        """A problem that ends the walk: an error when strict, else the end of what
        recovery reads (``dropped``: something was left out, which it reports)."""
        if self.strict:
            raise DamagedMcap(self.path, message)
        if dropped:
            self.scan.dropped.append(message)
        return False

    def step(self) -> bool:
        """Read one record; False when the data section (or the readable part) ends."""
        head = self.stream.read(RECORD_HEAD.size)
        if len(head) < RECORD_HEAD.size:
            return self.fail_or_stop(
                f"the file ends at offset {self.offset} without a DataEnd record", dropped=bool(head))
        opcode, length = RECORD_HEAD.unpack(head)
        left = self.size - self.offset - RECORD_HEAD.size
        if length > left:
            what = "chunk" if opcode == Opcode.CHUNK else f"record (opcode 0x{opcode:02x})"
            return self.fail_or_stop(f"the {what} at offset {self.offset} is cut short "
                                     f"({left} of {length} bytes)")
        body = self.stream.read(length)
        if opcode == Opcode.DATA_END:
            self.data_end(body)
            return False
        self.crc = zlib.crc32(body, zlib.crc32(head, self.crc))
        try:
            self.record(opcode, body)
        except BagError:
            raise
        except Exception as exc:  # a length or string field that does not fit its record
            return self.fail_or_stop(f"the record (opcode 0x{opcode:02x}) at offset "
                                     f"{self.offset} is malformed: {one_line(exc)}")
        self.offset += RECORD_HEAD.size + length
        return True

    def data_end(self, body: bytes) -> None:
        (stored,) = struct.unpack_from("<I", body)
        if stored == 0:
            self.fail_or_stop("the DataEnd record has no data section CRC")
        elif stored != self.crc:
            self.fail_or_stop(f"data section CRC mismatch (stored 0x{stored:08x}, "
                              f"computed 0x{self.crc:08x}): a byte outside the chunks changed")

    def record(self, opcode: int, body: bytes) -> None:
        from mcap.data_stream import ReadDataStream
        from mcap.records import Channel, Chunk, MessageIndex, Schema

        stream = ReadDataStream(BytesIO(body))
        if opcode == Opcode.HEADER:
            profile = stream.read_prefixed_string()
            if profile != "ros2":
                raise BagError(f"{self.path} is of another schema: MCAP profile {profile!r}, "
                               f"not 'ros2'")
        elif opcode == Opcode.SCHEMA:
            schema = Schema.read(stream)
            self.scan.schemas[schema.id] = schema
        elif opcode == Opcode.CHANNEL:
            channel = Channel.read(stream)
            self.scan.channels[channel.id] = channel
        elif opcode == Opcode.CHUNK:
            self.chunk(Chunk.read(stream))
        elif opcode == Opcode.MESSAGE_INDEX and self.scan.chunks:
            index = MessageIndex.read(stream)
            self.scan.chunks[-1].indexed[index.channel_id] += len(index.records)

    def chunk(self, chunk) -> None:
        from mcap.records import Channel, Message, Schema

        self.chunk_number += 1
        where = f"chunk {self.chunk_number} (offset {self.offset})"
        try:
            records = chunk_records(chunk, where)
        except BagError as exc:
            if self.strict:
                raise DamagedMcap(self.path, str(exc)) from None
            self.scan.dropped.append(str(exc))
            return
        seen = ChunkSeen(self.offset)
        scan = self.scan
        for record in records:
            if isinstance(record, Message):
                seen.counts[record.channel_id] += 1
                scan.start = record.log_time if scan.start is None else min(scan.start, record.log_time)
                scan.end = record.log_time if scan.end is None else max(scan.end, record.log_time)
                if self.keep:
                    scan.messages.append((record.log_time, record.channel_id, record.data))
            elif isinstance(record, Schema):
                scan.schemas[record.id] = record
            elif isinstance(record, Channel):
                scan.channels[record.id] = record
        scan.counts.update(seen.counts)
        scan.chunks.append(seen)


def scan_data_section(path: Path, *, strict: bool, keep_messages: bool = False) -> DataScan:
    """Walk the data section of ``path`` (see the module docstring)."""
    with path.open("rb") as stream:
        if stream.read(len(MAGIC)) != MAGIC:
            raise DamagedMcap(path, "not an MCAP file (no leading magic)")
        walker = _Walker(stream, path.stat().st_size, path, strict, keep_messages)
        while walker.step():
            pass
    return walker.scan


@dataclass
class Summary:
    """The records of a summary section that ``bag verify`` compares."""

    statistics: object
    chunk_indexes: list
    channels: dict
    schemas: dict


def summary_section(mcap: Path, require_crc: bool = True) -> bytes:
    """The summary section of a closed MCAP, after checking the summary CRC (a CRC
    of 0, "not computed", is an error only with ``require_crc``)."""
    with mcap.open("rb") as stream:
        size = stream.seek(0, os.SEEK_END)
        stream.seek(max(0, size - len(MAGIC) - FOOTER_SIZE))
        tail = stream.read()
        if len(tail) < len(MAGIC) + FOOTER_SIZE or tail[-len(MAGIC):] != MAGIC or tail[0] != 0x02:
            raise BagError(f"{mcap} has no footer (not closed cleanly? run `sensorispace bag recover`)")
        summary_start, _, stored = struct.unpack_from("<QQI", tail, RECORD_HEAD.size)
        if summary_start == 0 or summary_start > size - len(MAGIC) - FOOTER_SIZE:
            raise BagError(f"{mcap} has no summary section")
        if stored == 0:
            if require_crc:
                raise BagError(f"{mcap} has no summary CRC")
            return b""
        stream.seek(summary_start)
        section = stream.read(size - len(MAGIC) - FOOTER_SIZE - summary_start)
    computed = zlib.crc32(tail[:FOOTER_SIZE - 4], zlib.crc32(section))
    if computed != stored:
        raise BagError(f"{mcap}: summary CRC mismatch (stored 0x{stored:08x}, computed "
                       f"0x{computed:08x}): the summary or the footer changed")
    return section


def read_summary(mcap: Path) -> Summary:
    """Schemas, channels, chunk indexes and Statistics of the (CRC-checked) summary."""
    from mcap.data_stream import ReadDataStream
    from mcap.records import Channel, ChunkIndex, Schema, Statistics

    section = summary_section(mcap)
    summary = Summary(None, [], {}, {})
    readers = {Opcode.SCHEMA: Schema.read, Opcode.CHANNEL: Channel.read,
               Opcode.CHUNK_INDEX: ChunkIndex.read, Opcode.STATISTICS: Statistics.read}
    offset = 0
    while offset < len(section):
        opcode, length = RECORD_HEAD.unpack_from(section, offset)
        body = section[offset + RECORD_HEAD.size:offset + RECORD_HEAD.size + length]
        offset += RECORD_HEAD.size + length
        if opcode not in readers:
            continue
        try:
            record = readers[opcode](ReadDataStream(BytesIO(body)))
        except Exception as exc:
            raise BagError(f"{mcap}: a summary record (opcode 0x{opcode:02x}) is malformed: "
                           f"{one_line(exc)}") from None
        if opcode == Opcode.SCHEMA:
            summary.schemas[record.id] = record
        elif opcode == Opcode.CHANNEL:
            summary.channels[record.id] = record
        elif opcode == Opcode.CHUNK_INDEX:
            summary.chunk_indexes.append(record)
        else:
            summary.statistics = record
    return summary
