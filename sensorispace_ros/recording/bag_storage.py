"""The ``.mcap`` file of a bag: zstd-compressed chunks and every CRC MCAP defines.

``Rosbag2Writer`` is ``rosbags.rosbag2.Writer`` (which writes metadata.yaml:
rosbag2 version 9, type hashes, offered QoS, counts and times) with its MCAP
storage replaced by ``ZstdMcapStorage``, which writes through the official
``mcap.writer.Writer``:

- every chunk zstd-compressed (mcap's writer: zstd level 3, zstandard's
  default; the level is chosen in docs/bags.md);
- every chunk's ``uncompressed_crc``, the DataEnd ``data_section_crc`` and the
  footer's ``summary_crc`` (``enable_crcs`` + ``enable_data_crcs``);
- a summary with schemas, channels, Statistics, chunk and metadata indexes and
  summary offsets; the ``rosbag2`` metadata record (the serialized
  metadata.yaml) as Jazzy's MCAP storage writes it;
- ``ros2`` profile, ``ros2msg`` schemas from rosbags' Jazzy type store,
  ``cdr`` channels whose metadata holds ``offered_qos_profiles``.

The chunk compression is inside the storage, so metadata.yaml keeps
``compression_format: ''`` and ``compression_mode: ''`` (rosbag2 would
otherwise try to decompress the file or each message itself) and says what
the chunks are in ``custom_data`` (``CUSTOM_DATA``).

Chunks close only when asked (``flush_chunk``): the bag's writer decides when
(size and age: recording.bag_writer), so that it knows which messages reached
the operating system.
"""
from __future__ import annotations

from pathlib import Path

from rosbags.interfaces import MessageDefinitionFormat
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

# a Message record's bytes besides its data: opcode, length, channel, sequence, two times
MESSAGE_RECORD_OVERHEAD = 1 + 8 + 2 + 4 + 8 + 8
CUSTOM_DATA = {
    "mcap_chunk_compression": "zstd",
    "mcap_crcs": "chunk,data_section,summary",
}


class ZstdMcapStorage:
    """rosbags' storage-writer protocol (``path``, ``add_msgtype``,
    ``add_connection``, ``write``, ``close``, ``abort``) on ``mcap.writer.Writer``."""

    def __init__(self, path: Path, compression: CompressionMode) -> None:
        from mcap.writer import CompressionType
        from mcap.writer import Writer as McapWriter

        if compression != CompressionMode.STORAGE:
            raise ValueError(f"ZstdMcapStorage compresses its chunks itself, got {compression}")
        self.path = path / f"{path.name}.mcap"
        self._stream = self.path.open("xb")
        # chunk_size: no chunk closes by itself, flush_chunk closes them
        self._mcap = McapWriter(self._stream, chunk_size=2**62, compression=CompressionType.ZSTD,
                                enable_crcs=True, enable_data_crcs=True)
        self._mcap.start(profile="ros2")
        self._stream.flush()  # magic and header on disk: a killed writer leaves an MCAP
        self._schema_ids: dict[str, int] = {}
        self.catalogue: dict[str, dict[str, str]] = {}  # topic -> type and offered QoS
        self.open_chunk_bytes = 0
        self.open_chunk_messages = 0

    def add_msgtype(self, connection) -> None:
        encoding = ("ros2msg" if connection.msgdef.format == MessageDefinitionFormat.MSG
                    else "ros2idl")
        self._schema_ids[connection.msgtype] = self._mcap.register_schema(
            connection.msgtype, encoding, connection.msgdef.data.encode())

    def add_connection(self, connection, offered_qos_profiles: str) -> None:
        channel_id = self._mcap.register_channel(
            connection.topic, connection.ext.serialization_format,
            self._schema_ids[connection.msgtype], {"offered_qos_profiles": offered_qos_profiles})
        if channel_id != connection.id:  # rosbags and mcap both number from 1 in order
            raise RuntimeError(f"channel id {channel_id} != connection id {connection.id}")
        self.catalogue[connection.topic] = {"type": connection.msgtype,
                                            "offered_qos_profiles": offered_qos_profiles}

    def write(self, connection, timestamp: int, data: bytes | memoryview) -> None:
        self._mcap.add_message(connection.id, timestamp, bytes(data), timestamp)
        self.open_chunk_bytes += len(data) + MESSAGE_RECORD_OVERHEAD
        self.open_chunk_messages += 1

    def flush_chunk(self) -> bool:
        """Close the open chunk (compress, CRC, message indexes) and hand it to the
        operating system; False if it held no message."""
        if not self.open_chunk_bytes:
            return False
        self._mcap.flush()
        self.open_chunk_bytes = self.open_chunk_messages = 0
        return True

    def close(self, version: int, metadata: str) -> None:
        del version  # metadata.yaml's version is inside ``metadata``
        self._mcap.add_metadata("rosbag2", {"serialized_metadata": metadata})
        self._mcap.finish()
        self._stream.close()

    def abort(self) -> None:
        self._stream.close()


class Rosbag2Writer(Writer):
    """rosbags' rosbag2 writer on ``ZstdMcapStorage``."""

    STORAGE_PLUGINS = {StoragePlugin.MCAP: ZstdMcapStorage}

    def __init__(self, path: Path) -> None:
        super().__init__(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        for key, value in CUSTOM_DATA.items():
            self.set_custom_data(key, value)
