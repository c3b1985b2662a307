"""The one place that converts numpy arrays <-> ROS messages.

Tables travel as ``sensor_msgs/PointCloud2`` used as a typed record batch
(msg_schemas/topics.yaml): height 1, width = rows, little-endian, dense, one
``PointField`` per column (count 1, packed offsets). Packing is
``array.array('B', table.tobytes())`` and unpacking ``np.frombuffer`` —
measured at microseconds, where assigning an ndarray to a sequence field
costs ~0.5 ms (ROS_NOTES.md).

Decoding is strict: anything that does not match the expected layout exactly
(names, types, offsets, steps, data length, non-finite floats, unknown joint
names) raises ``MessageError``; nodes log and drop such messages.
"""
from __future__ import annotations

import array
import functools
from typing import Mapping, NamedTuple, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import JointState, PointCloud2, PointField
from std_msgs.msg import Header

JOINT_NAMES = ("joint1", "joint2", "joint3", "joint4")

# PointField datatype <-> little-endian numpy dtype (only the types the contract uses).
_FIELD_DTYPES = {
    "float64": (PointField.FLOAT64, np.dtype("<f8")),
    "uint32": (PointField.UINT32, np.dtype("<u4")),
    "int32": (PointField.INT32, np.dtype("<i4")),
    "uint8": (PointField.UINT8, np.dtype("u1")),
}


class MessageError(ValueError):
    """A message that does not match its topic's contract."""


class _Layout(NamedTuple):
    """What a table's columns fix about its cloud, computed once per contract."""
    dtype: np.dtype
    fields: tuple            # (name, offset, datatype, count) of each PointField
    float_only: bool         # every column float64: the data is a (rows, columns) matrix


@functools.lru_cache(maxsize=None)
def _layout(items: tuple) -> _Layout:
    try:
        dtype = np.dtype([(name, _FIELD_DTYPES[kind][1]) for name, kind in items])
    except KeyError as exc:
        raise ValueError(f"unsupported column type {exc.args[0]!r}; "
                         f"use one of {sorted(_FIELD_DTYPES)}") from None
    fields = tuple((name, dtype.fields[name][1], _FIELD_DTYPES[kind][0], 1)
                   for name, kind in items)
    return _Layout(dtype, fields, all(kind == "float64" for _, kind in items))


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
    """Pack a table (structured array, or {column: 1-D array}) as a PointCloud2."""
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
    if tuple((f.name, f.offset, f.datatype, f.count) for f in msg.fields) != layout.fields:
        names = [f.name for f in msg.fields]
        if names != list(columns):
            raise MessageError(f"fields {names} != expected {list(columns)}")
        for field, expected in zip(msg.fields, layout.fields):
            got = (field.offset, field.datatype, field.count)
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
    layout = _layout(tuple(columns.items()))
    records = np.frombuffer(msg.data, dtype=layout.dtype,
                            count=_checked_rows(msg, columns, layout))
    bad = _non_finite_column(records, columns)
    if bad is not None:
        raise MessageError(f"column {bad!r} holds NaN or inf")
    return records


def matrix_to_cloud(matrix: np.ndarray, columns: Mapping[str, str], header: Header) -> PointCloud2:
    """A float64 matrix ``(rows, len(columns))`` as a cloud of all-float64 columns."""
    matrix = np.asarray(matrix, dtype=float)
    layout = _layout(tuple(columns.items()))
    if matrix.ndim != 2 or matrix.shape[1] != len(columns):
        raise ValueError(f"matrix must have shape (rows, {len(columns)}), got {matrix.shape}")
    if not layout.float_only:
        raise ValueError("matrix_to_cloud needs float64 columns only")
    # A C-contiguous little-endian float64 matrix has exactly the packed record layout.
    return _cloud(layout, len(matrix), np.ascontiguousarray(matrix, dtype="<f8").tobytes(),
                  header)


def cloud_to_matrix(msg: PointCloud2, columns: Mapping[str, str]) -> np.ndarray:
    """Inverse of ``matrix_to_cloud``: a read-write float64 ``(rows, len(columns))`` array."""
    layout = _layout(tuple(columns.items()))
    if not layout.float_only:
        raise ValueError("cloud_to_matrix needs float64 columns only")
    n_rows = _checked_rows(msg, columns, layout)
    matrix = np.frombuffer(msg.data, dtype="<f8", count=n_rows * len(columns)).reshape(
        n_rows, len(columns))
    if not np.isfinite(matrix).all():
        bad = _non_finite_column(matrix.view(layout.dtype).reshape(-1), columns)
        raise MessageError(f"column {bad!r} holds NaN or inf")
    return matrix.astype(float)


class CloudPacker:
    """``matrix_to_cloud`` into one PointCloud2 re-filled at every ``pack``.

    For a node that packs and publishes a message per request (the body's
    replies): the fields, steps and flags are set once, and a pack sets only
    header, width, row_step and data (1 us instead of 15 us for a 1-row
    table). The returned message is valid until the next ``pack``: publish
    it before packing again (rclpy's publish copies it synchronously).
    """

    def __init__(self, columns: Mapping[str, str]):
        self._layout = _layout(tuple(columns.items()))
        if not self._layout.float_only:
            raise ValueError("CloudPacker needs float64 columns only")
        self._n_columns = len(columns)
        self.msg = _cloud(self._layout, 0, b"", Header())

    def pack(self, matrix: np.ndarray, header: Header) -> PointCloud2:
        matrix = np.asarray(matrix, dtype=float)
        if matrix.ndim != 2 or matrix.shape[1] != self._n_columns:
            raise ValueError(f"matrix must have shape (rows, {self._n_columns}), "
                             f"got {matrix.shape}")
        msg = self.msg
        msg.header = header
        msg.width = len(matrix)
        msg.row_step = self._layout.dtype.itemsize * len(matrix)
        msg.data = array.array("B", np.ascontiguousarray(matrix, dtype="<f8").tobytes())
        return msg


# ---------------------------------------------------------------- joint states

def motor_to_joint_state(motor_state: np.ndarray, header: Header,
                         names: Sequence[str] = JOINT_NAMES) -> JointState:
    motor_state = np.asarray(motor_state, dtype=float).reshape(-1)
    if len(motor_state) != len(names):
        raise ValueError(f"motor state has {len(motor_state)} joints, expected {len(names)}")
    return JointState(header=header, name=list(names), position=motor_state.tolist())


class JointStatePacker:
    """``motor_to_joint_state`` into one JointState re-filled at every ``pack``
    (names set once); valid until the next ``pack``, as ``CloudPacker``."""

    def __init__(self, names: Sequence[str] = JOINT_NAMES):
        self._n_joints = len(names)
        self.msg = JointState(name=list(names))

    def pack(self, motor_state: np.ndarray, header: Header) -> JointState:
        motor_state = np.asarray(motor_state, dtype=float).reshape(-1)
        if len(motor_state) != self._n_joints:
            raise ValueError(f"motor state has {len(motor_state)} joints, "
                             f"expected {self._n_joints}")
        self.msg.header = header
        self.msg.position = motor_state.tolist()
        return self.msg


def joint_state_to_motor(msg: JointState, names: Sequence[str] = JOINT_NAMES) -> np.ndarray:
    """Joint positions in the order of ``names``; unknown, missing or non-finite -> MessageError."""
    if list(msg.name) != list(names):
        raise MessageError(f"joint names {list(msg.name)} != expected {list(names)}")
    position = np.asarray(msg.position, dtype=float)
    if position.shape != (len(names),):
        raise MessageError(f"{len(position)} positions for {len(names)} joints")
    if not np.all(np.isfinite(position)):
        raise MessageError("joint positions hold NaN or inf")
    for extra in ("velocity", "effort"):
        values = list(getattr(msg, extra))
        if values and len(values) != len(names):
            raise MessageError(f"{len(values)} {extra} values for {len(names)} joints")
    return position
