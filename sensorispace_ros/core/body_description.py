"""What a body says of itself: its joints (name, unit, period) and its receptors.

This is the proprioceptive table a robot's joint list gives, and all the
naive agent and the representation may know of a body besides its
sensations. The body node publishes it on a latched topic; a user's own
body publishes one too and is then a drop-in (docs/own-body.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

UNITS = {"rad": 2.0 * np.pi, "deg": 360.0}       # unit -> period of a revolute joint


@dataclass(frozen=True)
class BodyDescription:
    """``joint_names``, ``unit`` ("rad" or "deg") and ``periods`` (one per
    joint, in ``unit``; a hinge turns once per period), and ``receptors``,
    the length of a sensation."""

    joint_names: tuple[str, ...]
    unit: str
    periods: tuple[float, ...]
    receptors: int

    def __post_init__(self):
        object.__setattr__(self, "joint_names", tuple(str(n) for n in self.joint_names))
        object.__setattr__(self, "periods", tuple(float(p) for p in self.periods))
        if not self.joint_names:
            raise ValueError("body description: needs at least one joint")
        if len(set(self.joint_names)) != len(self.joint_names):
            raise ValueError(f"body description: joint names repeat: {self.joint_names}")
        if self.unit not in UNITS:
            raise ValueError(f"body description: unit must be one of {sorted(UNITS)}, "
                             f"got {self.unit!r}")
        if len(self.periods) != len(self.joint_names):
            raise ValueError(f"body description: {len(self.joint_names)} joints but "
                             f"{len(self.periods)} periods")
        if not all(np.isfinite(p) and p > 0 for p in self.periods):
            raise ValueError(f"body description: periods must be finite and > 0, "
                             f"got {self.periods}")
        if int(self.receptors) != self.receptors or self.receptors < 1:
            raise ValueError(f"body description: receptors must be an integer >= 1, "
                             f"got {self.receptors!r}")
        object.__setattr__(self, "receptors", int(self.receptors))

    @classmethod
    def revolute(cls, n_joints: int, receptors: int, unit: str = "rad") -> "BodyDescription":
        """``n_joints`` hinges ``joint1..jointN`` of one turn per period of ``unit``."""
        if unit not in UNITS:
            raise ValueError(f"unit must be one of {sorted(UNITS)}, got {unit!r}")
        return cls(tuple(f"joint{k + 1}" for k in range(n_joints)), unit,
                   (UNITS[unit],) * n_joints, receptors)

    @property
    def n_motors(self) -> int:
        return len(self.joint_names)

    @property
    def motor_columns(self) -> tuple[str, ...]:
        return tuple(f"m{k}" for k in range(self.n_motors))

    @property
    def sensor_columns(self) -> tuple[str, ...]:
        return tuple(f"s{k}" for k in range(self.receptors))

    def to_radians(self, motor: np.ndarray) -> np.ndarray:
        """Motor values as angles, a period mapped to 2 pi (unchanged bits for radians)."""
        motor = np.asarray(motor, dtype=float)
        if all(p == 2.0 * np.pi for p in self.periods):
            return motor
        return motor * (2.0 * np.pi / np.asarray(self.periods))

    def from_radians(self, angles: np.ndarray) -> np.ndarray:
        """The inverse of ``to_radians``."""
        angles = np.asarray(angles, dtype=float)
        if all(p == 2.0 * np.pi for p in self.periods):
            return angles
        return angles * (np.asarray(self.periods) / (2.0 * np.pi))
