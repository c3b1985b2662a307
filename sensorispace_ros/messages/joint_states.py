"""Joint states and the body's description as ``sensor_msgs/JointState``
(``motor_to_joint_state`` and its serialized-bytes packer,
``description_to_msg`` / ``description_from_msg``)."""
from __future__ import annotations

from typing import Sequence

import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from sensorispace_ros.core.body_description import UNITS, BodyDescription
from sensorispace_ros.messages.clouds import (_ENCAPSULATION, _UINT32, MessageError,
                                              _cdr_header, _cdr_string, make_header)

# Bounds of what a description may announce: a malformed one must not make a
# node allocate for millions of columns.
MAX_RECEPTORS = 100_000
MAX_JOINTS = 10_000

def motor_to_joint_state(motor_state: np.ndarray, header: Header,
                         names: Sequence[str]) -> JointState:
    motor_state = np.asarray(motor_state, dtype=float).reshape(-1)
    if len(motor_state) != len(names):
        raise ValueError(f"motor state has {len(motor_state)} joints, expected {len(names)}")
    return JointState(header=header, name=list(names), position=motor_state.tolist())


class JointStateCdrPacker:
    """``motor_to_joint_state`` straight to serialized bytes (see
    ``CloudCdrPacker``): header, the names, the positions (float64, 8-aligned),
    empty velocity and effort."""

    def __init__(self, names: Sequence[str]):
        self._n_joints = len(names)
        position = len(_ENCAPSULATION)
        parts = [_UINT32.pack(len(names))]
        position += 4
        for name in names:
            parts.append(_cdr_string(name, position))
            position += len(parts[-1])
        self._names = b"".join(parts)        # from a 4-aligned start, 4-aligned end

    def pack(self, motor_state: np.ndarray, frame_id: str, stamp_ns: int = 0) -> bytes:
        motor_state = np.asarray(motor_state, dtype=float).reshape(-1)
        if len(motor_state) != self._n_joints:
            raise ValueError(f"motor state has {len(motor_state)} joints, "
                             f"expected {self._n_joints}")
        header = _cdr_header(frame_id, stamp_ns)
        count_end = len(header) + len(self._names) + 4        # after the positions' count
        padding = -(count_end - len(_ENCAPSULATION)) % 8      # float64: 8-aligned
        return b"".join((
            header, self._names,
            _UINT32.pack(self._n_joints), b"\x00" * padding,
            np.ascontiguousarray(motor_state, dtype="<f8").tobytes(),
            b"\x00" * 8))                                   # no velocity, no effort


def joint_state_to_motor(msg: JointState, names: Sequence[str]) -> np.ndarray:
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


# ---------------------------------------------------------------- the body's description

def description_to_msg(description: BodyDescription, stamp_ns: int = 0) -> JointState:
    """``description`` as /body/description carries it: names = the joints,
    positions = their periods, frame id ``<unit>/<receptors>``; no velocity, no effort."""
    return JointState(header=make_header(f"{description.unit}/{description.receptors}", stamp_ns),
                      name=list(description.joint_names), position=list(description.periods))


def description_from_msg(msg: JointState) -> BodyDescription:
    """The description a /body/description message carries; MessageError if it
    is malformed (frame id, names, periods, a velocity or effort, sizes)."""
    unit, slash, receptors = str(msg.header.frame_id).partition("/")
    if not slash or unit not in UNITS or not (receptors.isascii() and receptors.isdigit()) \
            or len(receptors) > 6:
        raise MessageError(f"frame id {msg.header.frame_id!r} is not <unit>/<receptors> "
                           f"with a unit of {sorted(UNITS)}")
    if not 1 <= int(receptors) <= MAX_RECEPTORS:
        raise MessageError(f"{receptors} receptors: must be 1..{MAX_RECEPTORS}")
    names, periods = list(msg.name), np.asarray(msg.position, dtype=float)
    if not 1 <= len(names) <= MAX_JOINTS:
        raise MessageError(f"{len(names)} joints: must be 1..{MAX_JOINTS}")
    if periods.shape != (len(names),):
        raise MessageError(f"{len(periods)} periods for {len(names)} joints")
    if len(msg.velocity) or len(msg.effort):
        raise MessageError("a description has no velocity and no effort")
    if not all(names):
        raise MessageError("a joint name is empty")
    try:
        return BodyDescription(tuple(names), unit, tuple(periods.tolist()), int(receptors))
    except ValueError as exc:         # repeated names, periods not finite and > 0
        raise MessageError(str(exc)) from None
