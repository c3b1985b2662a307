"""Tables as ``sensor_msgs/PointCloud2`` (typed record batches), and the
serialized-bytes path of the probe topics; see the package docstring."""
from __future__ import annotations

import array
import functools
import struct
from typing import Mapping, NamedTuple

import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

from sensorispace_ros import contracts

# PointField datatype <-> little-endian numpy dtype (only the types the contract uses).
_FIELD_DTYPES = {
    "float64": (PointField.FLOAT64, np.dtype("<f8")),
    "uint32": (PointField.UINT32, np.dtype("<u4")),
    "int32": (PointField.INT32, np.dtype("<i4")),
    "uint8": (PointField.UINT8, np.dtype("u1")),
    "uint16": (PointField.UINT16, np.dtype("<u2")),
    "float32": (PointField.FLOAT32, np.dtype("<f4")),      # the viewer's clouds
}
_KIND_OF_DATATYPE = {datatype: kind for kind, (datatype, _) in _FIELD_DTYPES.items()}

# A contract column of type ``number`` (a sensor's, /body/sensation) is any of
# NUMBER_TYPES, the same for every such column of a message, as its fields say;
# it is read as float64, and NaN in it is a lost frame, not a malformed message.
NUMBER = "number"
NUMBER_TYPES = contracts.NUMBER_TYPES


class MessageError(ValueError):
    """A message that does not match its topic's contract."""


class _Layout(NamedTuple):
    """What a table's columns fix about its cloud, computed once per contract."""
    dtype: np.dtype
    fields: tuple            # (name, offset, datatype, count) of each PointField
    uniform: np.dtype | None  # the one type of every column: the data is a (rows, columns) matrix


@functools.lru_cache(maxsize=None)
def _layout(items: tuple) -> _Layout:
    try:
        dtype = np.dtype([(name, _FIELD_DTYPES[kind][1]) for name, kind in items])
    except KeyError as exc:
        raise ValueError(f"unsupported column type {exc.args[0]!r}; "
                         f"use one of {sorted(_FIELD_DTYPES)}") from None
    fields = tuple((name, dtype.fields[name][1], _FIELD_DTYPES[kind][0], 1)
                   for name, kind in items)
    kinds = {kind for _, kind in items}
    uniform = _FIELD_DTYPES[kinds.pop()][1] if len(kinds) == 1 else None
    return _Layout(dtype, fields, uniform)


def _fields_of(msg) -> tuple:
    return (msg.field_tuples if isinstance(msg, SerializedCloud)
            else tuple((f.name, f.offset, f.datatype, f.count) for f in msg.fields))


def with_number_type(columns: Mapping[str, str], kind: str) -> dict:
    """``columns`` with each ``number`` column of type ``kind`` (one of NUMBER_TYPES):
    what a publisher of those columns writes."""
    if kind not in NUMBER_TYPES:
        raise ValueError(f"a number column is one of {', '.join(NUMBER_TYPES)}, got {kind!r}")
    return {name: kind if spec == NUMBER else spec for name, spec in columns.items()}


def _as_written(columns: Mapping[str, str]) -> Mapping[str, str]:
    """What a writer not told a type writes for ``number`` columns: float64."""
    return with_number_type(columns, "float64") if NUMBER in columns.values() else columns


def _resolved(msg, columns: Mapping[str, str]) -> Mapping[str, str]:
    """``columns`` with each ``number`` column of the type the message's first
    such field has (its other fields are checked against it later); MessageError
    when that is no number type."""
    numbers = [name for name, spec in columns.items() if spec == NUMBER]
    if not numbers:
        return columns
    datatype = next((field[2] for field in _fields_of(msg) if field[0] == numbers[0]), None)
    kind = _KIND_OF_DATATYPE.get(datatype)
    if kind not in NUMBER_TYPES:
        raise MessageError(f"field {numbers[0]!r}: datatype {datatype} is not one of "
                           f"{', '.join(NUMBER_TYPES)}")
    return with_number_type(columns, kind)


def record_dtype(columns: Mapping[str, str]) -> np.dtype:
    """Packed structured dtype of a table with ``columns`` ({name: type name})."""
    return _layout(tuple(columns.items())).dtype


def make_header(frame_id: str, stamp_ns: int = 0) -> Header:
    stamp_ns = int(stamp_ns)
    return Header(stamp=Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000),
                  frame_id=str(frame_id))


def stamp_ns(header: Header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


# ---------------------------------------------------------------- tables

def _cloud(layout: _Layout, n_rows: int, data: bytes, header: Header) -> PointCloud2:
    # Fresh PointField objects each time: a caller may edit a message it built.
    fields = [PointField(name=name, offset=offset, datatype=datatype, count=count)
              for name, offset, datatype, count in layout.fields]
    return PointCloud2(header=header, height=1, width=n_rows, fields=fields,
                       is_bigendian=False, point_step=layout.dtype.itemsize,
                       row_step=layout.dtype.itemsize * n_rows,
                       data=array.array("B", data), is_dense=True)


def table_to_cloud(table: np.ndarray | Mapping[str, np.ndarray], columns: Mapping[str, str],
                   header: Header) -> PointCloud2:
    """Pack a table (structured array, or {column: 1-D array}) as a PointCloud2
    (``number`` columns as float64)."""
    columns = _as_written(columns)
    layout = _layout(tuple(columns.items()))
    dtype = layout.dtype
    if isinstance(table, np.ndarray) and table.dtype.names is not None:
        if tuple(table.dtype.names) != tuple(columns):
            raise ValueError(f"table columns {table.dtype.names} != contract {tuple(columns)}")
        records = table.astype(dtype, copy=False)
    else:
        lengths = {name: len(np.atleast_1d(table[name])) for name in columns}
        if len(set(lengths.values())) > 1:
            raise ValueError(f"columns have different lengths: {lengths}")
        records = np.empty(next(iter(lengths.values()), 0), dtype=dtype)
        for name in columns:
            records[name] = np.atleast_1d(table[name])
    records = np.ascontiguousarray(records).reshape(-1)
    return _cloud(layout, len(records), records.tobytes(), header)


def _checked_rows(msg: PointCloud2, columns: Mapping[str, str], layout: _Layout) -> int:
    """Number of rows of a cloud whose layout is exactly ``layout``; else MessageError."""
    fields = _fields_of(msg)
    if fields != layout.fields:
        names = [field[0] for field in fields]
        if names != list(columns):
            raise MessageError(f"fields {names} != expected {list(columns)}")
        for field, expected in zip(fields, layout.fields):
            got = field[1:]
            if got != expected[1:]:
                raise MessageError(f"field {expected[0]!r}: (offset, datatype, count) = "
                                   f"{got}, expected {expected[1:]}")
    itemsize = layout.dtype.itemsize
    if msg.is_bigendian:
        raise MessageError("big-endian data is not accepted")
    if msg.point_step != itemsize:
        raise MessageError(f"point_step {msg.point_step} != {itemsize}")
    height, width = msg.height, msg.width
    if height != 1 and width * height != 0:
        raise MessageError(f"height must be 1, got {height}")
    if msg.row_step != width * msg.point_step:
        raise MessageError(f"row_step {msg.row_step} != width {width} * point_step {msg.point_step}")
    n_rows = width if height else 0
    if len(msg.data) != n_rows * itemsize:
        raise MessageError(f"data holds {len(msg.data)} bytes, expected {n_rows * itemsize}")
    return n_rows


def _non_finite_column(records: np.ndarray, columns: Mapping[str, str]) -> str | None:
    for name, kind in columns.items():
        if kind == "float64" and not np.all(np.isfinite(records[name])):
            return name
    return None


def cloud_to_table(msg: PointCloud2, columns: Mapping[str, str]) -> np.ndarray:
    """Unpack a PointCloud2 into a structured array, checking it against ``columns``."""
    columns = _resolved(msg, columns)
    layout = _layout(tuple(columns.items()))
    records = np.frombuffer(msg.data, dtype=layout.dtype,
                            count=_checked_rows(msg, columns, layout))
    bad = _non_finite_column(records, columns)
    if bad is not None:
        raise MessageError(f"column {bad!r} holds NaN or inf")
    return records


def cloud_column(msg: PointCloud2, name: str, kind: str) -> np.ndarray:
    """Column ``name`` (type ``kind``) of a cloud whatever its other columns, for
    a reader that needs that one only; MessageError unless the cloud is a
    little-endian table of one row per point that holds it once."""
    fields = _fields_of(msg)
    datatype, dtype = _FIELD_DTYPES[kind]
    found = [field for field in fields if field[0] == name]
    if len(found) != 1 or found[0][2:] != (datatype, 1):
        raise MessageError(f"no single {kind} column {name!r} in fields "
                           f"{[field[0] for field in fields]}")
    offset, point_step, width = found[0][1], msg.point_step, msg.width
    if msg.is_bigendian:
        raise MessageError("big-endian data is not accepted")
    if offset + dtype.itemsize > point_step:
        raise MessageError(f"column {name!r} at {offset} overruns point_step {point_step}")
    if msg.height != 1 and width * msg.height != 0:
        raise MessageError(f"height must be 1, got {msg.height}")
    n_rows = width if msg.height else 0
    if msg.row_step != width * point_step or len(msg.data) != n_rows * point_step:
        raise MessageError(f"row_step {msg.row_step} / {len(msg.data)} data bytes do not "
                           f"fit {n_rows} rows of {point_step} bytes")
    if n_rows == 0:
        return np.zeros(0, dtype)
    return np.ndarray((n_rows,), dtype, bytes(msg.data), offset, (point_step,)).copy()


def _uniform_layout(columns: Mapping[str, str], caller: str) -> _Layout:
    layout = _layout(tuple(columns.items()))
    if layout.uniform is None:
        raise ValueError(f"{caller} needs columns of one type, got {dict(columns)}")
    return layout


def matrix_to_cloud(matrix: np.ndarray, columns: Mapping[str, str], header: Header) -> PointCloud2:
    """A matrix ``(rows, len(columns))`` as a cloud of columns of one type (float64,
    or another: the values cast to it; ``number`` columns as float64)."""
    layout = _uniform_layout(_as_written(columns), "matrix_to_cloud")
    matrix = np.asarray(matrix)
    if matrix.ndim != 2 or matrix.shape[1] != len(columns):
        raise ValueError(f"matrix must have shape (rows, {len(columns)}), got {matrix.shape}")
    # A C-contiguous little-endian matrix of the columns' type has exactly the packed layout.
    return _cloud(layout, len(matrix),
                  np.ascontiguousarray(matrix, dtype=layout.uniform).tobytes(), header)


def cloud_to_matrix(msg: PointCloud2, columns: Mapping[str, str]) -> np.ndarray:
    """Inverse of ``matrix_to_cloud``: a read-write float64 ``(rows, len(columns))``
    array, of columns of one type (``number`` columns: as the message's fields
    say; NaN allowed in them, a lost frame)."""
    numbers = NUMBER in columns.values()
    columns = _resolved(msg, columns)
    layout = _uniform_layout(columns, "cloud_to_matrix")
    n_rows = _checked_rows(msg, columns, layout)
    matrix = np.frombuffer(msg.data, dtype=layout.uniform, count=n_rows * len(columns)).reshape(
        n_rows, len(columns)).astype(float)
    if layout.uniform.kind == "f" and not np.isfinite(matrix).all():
        bad = (np.isinf(matrix) if numbers else ~np.isfinite(matrix)).any(axis=0)
        if bad.any():
            raise MessageError(f"column {list(columns)[int(np.argmax(bad))]!r} holds "
                               + ("inf" if numbers else "NaN or inf"))
    return matrix


# ---------------------------------------------------------------- serialized clouds
#
# ROS 2's CDR (XCDR1) little-endian: a 4-byte encapsulation header 00 01 xx xx,
# then the members in order, each aligned to its size counted from the byte
# after that header; a string is a uint32 length (NUL included), its bytes and
# the NUL; a sequence a uint32 count and its elements. PointCloud2 has no
# member wider than 4 bytes.

_CDR_LE = b"\x00\x01"
_ENCAPSULATION = b"\x00\x01\x00\x00"
_UINT32 = struct.Struct("<I")
_THREE_UINT32 = struct.Struct("<III")
_STAMP = struct.Struct("<iI")                    # stamp.sec, stamp.nanosec
_STAMP_AND_LENGTH = struct.Struct("<iII")       # stamp.sec, stamp.nanosec, len(frame_id) + 1
_FIELD_TAIL = struct.Struct("<IB3xI")            # offset, datatype, (pad), count


def _aligned(position: int) -> int:
    """``position`` (index in the bytes) rounded up to 4 from the encapsulation's end."""
    return position + (-(position - len(_ENCAPSULATION)) % 4)


def _cdr_string(text: str, position: int) -> bytes:
    """A CDR string written at 4-aligned ``position``, with the padding that
    4-aligns what follows it."""
    encoded = text.encode("utf-8") + b"\x00"
    end = position + 4 + len(encoded)
    return _UINT32.pack(len(encoded)) + encoded + b"\x00" * (_aligned(end) - end)


def _cdr_header(frame_id: str, stamp_ns: int) -> bytes:
    """Encapsulation and ``std_msgs/Header`` (stamp, frame_id), padded so that
    what follows is 4-aligned: how both packers' messages begin."""
    stamp_ns = int(stamp_ns)
    stamp = _STAMP.pack(stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000)
    return b"".join((_ENCAPSULATION, stamp,
                     _cdr_string(frame_id, len(_ENCAPSULATION) + len(stamp))))


def _cdr_fields(fields: tuple) -> bytes:
    """The ``fields`` sequence of a cloud, from its count on, as written at a
    4-aligned position (its bytes do not depend on which)."""
    out = [_UINT32.pack(len(fields))]
    position = len(_ENCAPSULATION) + 4   # after the count, from any 4-aligned start
    for name, offset, datatype, count in fields:
        name_bytes = _cdr_string(name, position)
        out += [name_bytes, _FIELD_TAIL.pack(offset, datatype, count)]
        position += len(name_bytes) + _FIELD_TAIL.size
    return b"".join(out)


class TimeView(NamedTuple):
    sec: int
    nanosec: int


class HeaderView(NamedTuple):
    """The header of a ``SerializedCloud``: what a Header offers the nodes."""
    stamp: TimeView
    frame_id: str


class SerializedCloud(NamedTuple):
    """A PointCloud2 read from its CDR bytes: the members the decoders check,
    ``field_tuples`` in place of ``fields``, ``data`` a view of the bytes."""
    header: HeaderView
    height: int
    width: int
    field_tuples: tuple          # (name, offset, datatype, count) of each field
    is_bigendian: bool
    point_step: int
    row_step: int
    data: memoryview
    is_dense: bool


def cloud_from_cdr(raw: bytes) -> SerializedCloud:
    """Parse a PointCloud2's serialized bytes (a ``raw=True`` subscription's
    message); bytes that are not a well-formed little-endian CDR PointCloud2
    raise MessageError. The layout is checked later, by ``cloud_to_matrix`` /
    ``cloud_to_table``, as for a PointCloud2."""
    if not isinstance(raw, (bytes, bytearray)):
        raise MessageError(f"expected serialized bytes, got {type(raw).__name__}")
    if raw[:2] != _CDR_LE or len(raw) < len(_ENCAPSULATION):
        raise MessageError(f"not little-endian CDR (encapsulation {bytes(raw[:4]).hex()})")
    try:
        sec, nanosec, length = _STAMP_AND_LENGTH.unpack_from(raw, 4)
        start = 4 + _STAMP_AND_LENGTH.size
        end = start + length
        if length < 1 or end > len(raw) or raw[end - 1] != 0:
            raise MessageError("header.frame_id is not a NUL-terminated string")
        frame_id = raw[start:end - 1].decode("utf-8")
        position = _aligned(end)
        height, width, n_fields = _THREE_UINT32.unpack_from(raw, position)
        fields, position = _parse_fields(raw, position + 12, n_fields)
        is_bigendian = raw[position]
        point_step, row_step, n_data = _THREE_UINT32.unpack_from(raw, _aligned(position + 1))
        data_at = _aligned(position + 1) + 12
        if data_at + n_data >= len(raw):
            raise MessageError(f"data of {n_data} bytes overruns the message "
                               f"({len(raw)} bytes)")
        is_dense = raw[data_at + n_data]
    except (struct.error, IndexError):
        raise MessageError(f"truncated serialized PointCloud2 ({len(raw)} bytes)") from None
    except UnicodeDecodeError as exc:
        raise MessageError(f"a string is not UTF-8: {exc}") from None
    if is_bigendian > 1 or is_dense > 1:
        raise MessageError("a bool member is neither 0 nor 1")
    return SerializedCloud(HeaderView(TimeView(sec, nanosec), frame_id), height, width, fields,
                           bool(is_bigendian), point_step, row_step,
                           memoryview(raw)[data_at:data_at + n_data], bool(is_dense))


def _parse_fields(raw: bytes, position: int, n_fields: int) -> tuple[tuple, int]:
    if n_fields > len(raw):                  # each field takes more than a byte
        raise MessageError(f"{n_fields} fields in a message of {len(raw)} bytes")
    fields = []
    for _ in range(n_fields):
        (length,) = _UINT32.unpack_from(raw, position)
        start, end = position + 4, position + 4 + length
        if length < 1 or end > len(raw) or raw[end - 1] != 0:
            raise MessageError("a field name is not a NUL-terminated string")
        name = raw[start:end - 1].decode("utf-8")
        offset, datatype, count = _FIELD_TAIL.unpack_from(raw, _aligned(end))
        fields.append((name, offset, datatype, count))
        position = _aligned(end) + _FIELD_TAIL.size
    return tuple(fields), position


class CloudCdrPacker:
    """``matrix_to_cloud`` straight to serialized bytes, for ``publish(bytes)``,
    without building the message: rclpy reads them as the PointCloud2
    ``matrix_to_cloud`` builds (checked in the tests)."""

    def __init__(self, columns: Mapping[str, str]):
        self._layout = _uniform_layout(_as_written(columns), "CloudCdrPacker")
        self._n_columns = len(columns)
        self._fields = _cdr_fields(self._layout.fields)

    def pack(self, matrix: np.ndarray, frame_id: str, stamp_ns: int = 0) -> bytes:
        matrix = np.asarray(matrix)
        if matrix.ndim != 2 or matrix.shape[1] != self._n_columns:
            raise ValueError(f"matrix must have shape (rows, {self._n_columns}), "
                             f"got {matrix.shape}")
        point_step = self._layout.dtype.itemsize
        data = np.ascontiguousarray(matrix, dtype=self._layout.uniform).tobytes()
        return b"".join((
            _cdr_header(frame_id, stamp_ns),
            _UINT32.pack(1), _UINT32.pack(len(matrix)),              # height, width
            self._fields,
            b"\x00\x00\x00\x00",                                   # is_bigendian, padding
            _THREE_UINT32.pack(point_step, point_step * len(matrix), len(data)),
            data, b"\x01"))                                         # is_dense


class FloatCloud(NamedTuple):
    """What ``CloudCdrReader.read`` gets from a float cloud's bytes."""
    frame_id: str
    stamp_ns: int
    matrix: np.ndarray           # (rows, columns) float64, a copy the caller owns


_HEIGHT_WIDTH = struct.Struct("<II")
_NANOSECONDS_PER_SECOND = 1_000_000_000


class CloudCdrReader:
    """``cloud_to_matrix(cloud_from_cdr(raw), columns)`` for the bytes of one
    contract whose columns share a type (``number`` columns: each of
    NUMBER_TYPES, the last one read tried first), with the frame id and stamp.

    Bytes laid out exactly as ``CloudCdrPacker`` writes them (what the probe
    topics carry) are checked by comparing the fields section, steps, lengths
    and flags with the contract's, and the data copied out with one numpy
    call, about half the general path's cost on every probe message. Anything
    else
    (an rclpy-serialized message, whose padding bytes are unset, or a
    malformed one) goes the general path: the same result, or the same
    MessageError."""

    def __init__(self, columns: Mapping[str, str]):
        self._columns = dict(columns)
        kinds = NUMBER_TYPES if NUMBER in self._columns.values() else (None,)
        self._n_columns = len(self._columns)
        # Per type the columns may have: (fields sequence then is_bigendian False and
        # its padding, point step, dtype); the type last read first.
        self._layouts = []
        for kind in kinds:
            layout = _uniform_layout(self._columns if kind is None
                                     else with_number_type(self._columns, kind), "CloudCdrReader")
            self._layouts.append((_cdr_fields(layout.fields) + b"\x00\x00\x00\x00",
                                  layout.dtype.itemsize, layout.uniform))

    def read(self, raw: bytes) -> FloatCloud:
        """The cloud in ``raw`` (a ``raw=True`` subscription's message); bytes
        that break the contract raise MessageError as ``cloud_from_cdr`` /
        ``cloud_to_matrix`` do."""
        cloud = self.read_packed(raw)
        if cloud is None:
            general = cloud_from_cdr(raw)
            cloud = FloatCloud(general.header.frame_id, stamp_ns(general.header),
                               cloud_to_matrix(general, self._columns))
        return cloud

    def read_packed(self, raw) -> FloatCloud | None:
        """The cloud in ``raw`` if its bytes are laid out exactly as
        ``CloudCdrPacker`` writes them and hold finite floats; otherwise None,
        for ``read``'s general path (which accepts or rejects it)."""
        if type(raw) is not bytes or not raw.startswith(_CDR_LE):
            return None
        try:
            sec, nanosec, length = _STAMP_AND_LENGTH.unpack_from(raw, 4)
            end = 16 + length                          # after frame_id's NUL
            if length < 1 or raw[end - 1] != 0:
                return None
            frame_id = raw[16:end - 1].decode("utf-8")
            position = end + (-end % 4)                # _aligned(end): 4 is aligned
            height, width = _HEIGHT_WIDTH.unpack_from(raw, position)
            position += 8
            if height != 1:
                return None
            for k, (fields, step, dtype) in enumerate(self._layouts):
                if raw.startswith(fields, position):
                    break
            else:
                return None
            if k:
                self._layouts.insert(0, self._layouts.pop(k))
            position += len(fields)
            point_step, row_step, n_data = _THREE_UINT32.unpack_from(raw, position)
        except (struct.error, IndexError, UnicodeDecodeError):
            return None
        position += 12
        row_step_expected = width * step
        dense_at = position + n_data
        # Between processes Fast DDS hands over the payload padded to a multiple
        # of 4 bytes (CDR's alignment; the general path ignores trailing bytes),
        # so up to 3 trailing bytes are accepted here too.
        if (point_step != step or row_step != row_step_expected
                or n_data != row_step_expected or not 0 <= len(raw) - dense_at - 1 <= 3
                or raw[dense_at] != 1):
            return None
        matrix = np.ndarray((width, self._n_columns), dtype, raw, position).astype(float)
        if dtype.kind == "f" and not np.isfinite(matrix).all():
            return None                                # the general path names the column
        return FloatCloud(frame_id, sec * _NANOSECONDS_PER_SECOND + nanosec, matrix)
