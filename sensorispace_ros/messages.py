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
from typing import Mapping, Sequence

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


def record_dtype(columns: Mapping[str, str]) -> np.dtype:
    """Packed structured dtype of a table with ``columns`` ({name: type name})."""
    try:
        return np.dtype([(name, _FIELD_DTYPES[kind][1]) for name, kind in columns.items()])
    except KeyError as exc:
        raise ValueError(f"unsupported column type {exc.args[0]!r}; "
                         f"use one of {sorted(_FIELD_DTYPES)}") from None


def make_header(frame_id: str, stamp_ns: int = 0) -> Header:
    stamp_ns = int(stamp_ns)
    return Header(stamp=Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000),
                  frame_id=str(frame_id))


def stamp_ns(header: Header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


# ---------------------------------------------------------------- tables

def table_to_cloud(table: np.ndarray | Mapping[str, np.ndarray], columns: Mapping[str, str],
                   header: Header) -> PointCloud2:
    """Pack a table (structured array, or {column: 1-D array}) as a PointCloud2."""
    dtype = record_dtype(columns)
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
    fields = [PointField(name=name, offset=dtype.fields[name][1],
                         datatype=_FIELD_DTYPES[kind][0], count=1)
              for name, kind in columns.items()]
    return PointCloud2(header=header, height=1, width=len(records), fields=fields,
                       is_bigendian=False, point_step=dtype.itemsize,
                       row_step=dtype.itemsize * len(records),
                       data=array.array("B", records.tobytes()), is_dense=True)


def cloud_to_table(msg: PointCloud2, columns: Mapping[str, str]) -> np.ndarray:
    """Unpack a PointCloud2 into a structured array, checking it against ``columns``."""
    dtype = record_dtype(columns)
    names = [f.name for f in msg.fields]
    if names != list(columns):
        raise MessageError(f"fields {names} != expected {list(columns)}")
    for field, (name, kind) in zip(msg.fields, columns.items()):
        expected = (dtype.fields[name][1], _FIELD_DTYPES[kind][0], 1)
        if (field.offset, field.datatype, field.count) != expected:
            raise MessageError(f"field {name!r}: (offset, datatype, count) = "
                               f"{(field.offset, field.datatype, field.count)}, expected {expected}")
    if msg.is_bigendian:
        raise MessageError("big-endian data is not accepted")
    if msg.point_step != dtype.itemsize:
        raise MessageError(f"point_step {msg.point_step} != {dtype.itemsize}")
    if msg.height != 1 and msg.width * msg.height != 0:
        raise MessageError(f"height must be 1, got {msg.height}")
    if msg.row_step != msg.width * msg.point_step:
        raise MessageError(f"row_step {msg.row_step} != width {msg.width} * point_step {msg.point_step}")
    n_rows = msg.width if msg.height else 0
    if len(msg.data) != n_rows * dtype.itemsize:
        raise MessageError(f"data holds {len(msg.data)} bytes, expected {n_rows * dtype.itemsize}")
    records = np.frombuffer(msg.data, dtype=dtype, count=n_rows)
    for name, kind in columns.items():
        if kind == "float64" and not np.all(np.isfinite(records[name])):
            raise MessageError(f"column {name!r} holds NaN or inf")
    return records


def matrix_to_cloud(matrix: np.ndarray, columns: Mapping[str, str], header: Header) -> PointCloud2:
    """A float64 matrix ``(rows, len(columns))`` as a cloud of all-float64 columns."""
    matrix = np.asarray(matrix, dtype=float)
    if matrix.ndim != 2 or matrix.shape[1] != len(columns):
        raise ValueError(f"matrix must have shape (rows, {len(columns)}), got {matrix.shape}")
    if any(kind != "float64" for kind in columns.values()):
        raise ValueError("matrix_to_cloud needs float64 columns only")
    # A C-contiguous float64 matrix has exactly the packed record layout.
    return table_to_cloud(np.ascontiguousarray(matrix, dtype="<f8").view(record_dtype(columns))
                          .reshape(-1), columns, header)


def cloud_to_matrix(msg: PointCloud2, columns: Mapping[str, str]) -> np.ndarray:
    """Inverse of ``matrix_to_cloud``: a read-write float64 ``(rows, len(columns))`` array."""
    if any(kind != "float64" for kind in columns.values()):
        raise ValueError("cloud_to_matrix needs float64 columns only")
    records = cloud_to_table(msg, columns)
    return records.view("<f8").reshape(len(records), len(columns)).astype(float)


# ---------------------------------------------------------------- joint states

def motor_to_joint_state(motor_state: np.ndarray, header: Header,
                         names: Sequence[str] = JOINT_NAMES) -> JointState:
    motor_state = np.asarray(motor_state, dtype=float).reshape(-1)
    if len(motor_state) != len(names):
        raise ValueError(f"motor state has {len(motor_state)} joints, expected {len(names)}")
    return JointState(header=header, name=list(names), position=motor_state.tolist())


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
