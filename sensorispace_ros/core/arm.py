"""Planar serial arms: any chain of hinged links with an eye at the tip
(paper Sec. 2.3: three unit segments and a fourth joint turning the eye).

``Arm(segments, eye, unit)``: one hinge per link; ``eye`` is ``"joint"`` (a
last hinge turns the eye: the paper), ``"link"`` (the eye is fixed to the
last link) or ``"level"`` (the eye keeps the world direction
``LEVEL_DIRECTION``, a stabilised camera). The sensor pose is ``(x, y,
alpha)`` of the eye; motor values are in ``unit`` (``rad`` or ``deg``).
The module functions ``forward``/``jacobian`` are the paper arm's, written
out for its three unit segments; ``Arm`` methods take that path for it.
All functions broadcast over leading axes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensorispace_ros.core.body_description import UNITS, BodyDescription

N_JOINTS = 4
SEGMENT_LENGTHS = (1.0, 1.0, 1.0)
EYES = ("joint", "link", "level")
LEVEL_DIRECTION = 0.0            # world direction of a level eye (rad)


def _segment_angles(motor: np.ndarray) -> np.ndarray:
    """Absolute orientation of each of the three segments."""
    return np.cumsum(motor[..., :3], axis=-1)


def forward(motor: np.ndarray, lengths=SEGMENT_LENGTHS) -> np.ndarray:
    """Forward model f(m) -> (x_tip, y_tip, alpha_tip), paper Eq. (forwardmodel).

    ``alpha_tip`` is the unwrapped sum of the joint angles; compare angles
    with ``wrap_angle`` of their difference.
    """
    motor = np.asarray(motor, dtype=float)
    if motor.ndim == 0 or motor.shape[-1] < 3:
        raise ValueError(f"motor must have shape (..., {N_JOINTS}), got {motor.shape}")
    # One joint per row: the sums run as whole-row additions (numpy's cumsum /
    # sum over a short last axis loop per batch row, slower) and add left to
    # right, as cumsum does, so the bits are the same
    # (tests/core/test_body_simulation.py).
    joints = motor.reshape(-1, motor.shape[-1]).T
    theta = np.empty((3, joints.shape[1]))
    np.add(joints[0], joints[1], out=theta[1])
    np.add(theta[1], joints[2], out=theta[2])
    theta[0] = joints[0]
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    if lengths is not SEGMENT_LENGTHS:   # x * 1.0 is exact: unit segments skip it
        lengths = np.broadcast_to(np.asarray(lengths, dtype=float), (3,))[:, None]
        cos_t *= lengths
        sin_t *= lengths
    pose = np.empty((joints.shape[1], 3))
    np.add(cos_t[0], cos_t[1], out=pose[:, 0])
    pose[:, 0] += cos_t[2]
    np.add(sin_t[0], sin_t[1], out=pose[:, 1])
    pose[:, 1] += sin_t[2]
    np.add(joints[0], joints[1], out=pose[:, 2])
    for column in joints[2:]:
        pose[:, 2] += column
    return pose.reshape(motor.shape[:-1] + (3,))


def jacobian(motor: np.ndarray, lengths=SEGMENT_LENGTHS) -> np.ndarray:
    """Analytic Jacobian df/dm, shape ``(..., 3, 4)``."""
    motor = np.asarray(motor, dtype=float)
    theta = _segment_angles(motor)
    lengths = np.asarray(lengths, dtype=float)
    # Joint k moves every segment from k on: sum the tails of the chain.
    tail_x = np.cumsum((lengths * np.cos(theta))[..., ::-1], axis=-1)[..., ::-1]
    tail_y = np.cumsum((lengths * np.sin(theta))[..., ::-1], axis=-1)[..., ::-1]
    jac = np.zeros(motor.shape[:-1] + (3, N_JOINTS))
    jac[..., 0, :3] = -tail_y
    jac[..., 1, :3] = tail_x
    jac[..., 2, :] = 1.0
    return jac


def kernel_direction(jac: np.ndarray) -> np.ndarray:
    """Null vector of a ``(..., 3, 4)`` Jacobian from its signed 3x3 minors.

    The generalised cross product varies continuously with the Jacobian, so
    successive steps of a kernel walk keep their direction; an SVD null
    vector flips sign arbitrarily (paper's gamma = +-1 bookkeeping).
    """
    jac = np.asarray(jac, dtype=float)
    cols = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]
    minors = [np.linalg.det(jac[..., :, c]) for c in cols]
    signs = np.array([1.0, -1.0, 1.0, -1.0])
    return np.stack([s * d for s, d in zip(signs, minors)], axis=-1)


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Map angles to [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def pose_error(pose_a: np.ndarray, pose_b: np.ndarray) -> np.ndarray:
    """Euclidean norm of a pose difference, the orientation taken modulo 2 pi."""
    diff = np.asarray(pose_a, dtype=float) - np.asarray(pose_b, dtype=float)
    diff = np.concatenate([diff[..., :2], wrap_angle(diff[..., 2:])], axis=-1)
    return np.linalg.norm(diff, axis=-1)


@dataclass(frozen=True)
class Arm:
    """A planar chain: link lengths ``segments``, the eye's mount, the motor unit."""

    segments: tuple = SEGMENT_LENGTHS
    eye: str = "joint"
    unit: str = "rad"

    def __post_init__(self):
        segments = tuple(float(v) for v in np.atleast_1d(np.asarray(self.segments, float)))
        object.__setattr__(self, "segments", segments)
        if not segments:
            raise ValueError("arm.segments: needs at least one link, got []")
        if not all(np.isfinite(v) and v > 0 for v in segments):
            raise ValueError(f"arm.segments: every link length must be finite and > 0, "
                             f"got {list(segments)}")
        if self.eye not in EYES:
            raise ValueError(f"arm.eye: must be one of {', '.join(EYES)}, got {self.eye!r}")
        if self.unit not in UNITS:
            raise ValueError(f"arm.motor_unit: must be one of {', '.join(UNITS)}, "
                             f"got {self.unit!r}")
        # Read on every simulated batch: kept, not recomputed.
        object.__setattr__(self, "_joints", len(segments) + (self.eye == "joint"))
        object.__setattr__(self, "_paper", segments == SEGMENT_LENGTHS and self.eye == "joint"
                           and self.unit == "rad")

    @classmethod
    def from_config(cls, arm_cfg: dict) -> "Arm":
        """The arm of a configuration's ``arm`` section."""
        return cls(tuple(arm_cfg["segments"]), arm_cfg["eye"], arm_cfg["motor_unit"])

    @property
    def n_links(self) -> int:
        return len(self.segments)

    @property
    def n_joints(self) -> int:
        return self._joints

    @property
    def pose_rank(self) -> int:
        """Degrees of freedom of the eye's pose over the joints (generic rank of J)."""
        return min(self.n_joints, 2 + (self.eye != "level"))

    @property
    def pov_dim(self) -> int:
        """Dimension of a point of view: joints the pose leaves free."""
        return self.n_joints - self.pose_rank

    @property
    def reach(self) -> float:
        return float(sum(self.segments))

    @property
    def inner_reach(self) -> float:
        """Radius of the hole the tip cannot enter (0 when it can reach the base)."""
        return max(0.0, 2.0 * max(self.segments) - self.reach)

    @property
    def working_ring(self) -> tuple[float, float]:
        """Tip radii at least one link from the base and within reach (the
        paper arm's unsplit points of view: 1 <= |tip| <= 3)."""
        return (min(self.segments[0], self.reach), self.reach)

    @property
    def is_paper(self) -> bool:
        """The paper's arm: three unit links, an eye joint, radians."""
        return self._paper

    @property
    def period(self) -> float:
        """A full turn of a joint in its unit."""
        return UNITS[self.unit]

    def reachable(self, position: np.ndarray, orientation: float) -> np.ndarray:
        """Whether the eye can be at ``position`` ``(..., 2)`` with the world
        ``orientation`` it has (geometry alone: the workspace of the chain,
        and for an eye fixed to its link, of the links before the last)."""
        position = np.asarray(position, dtype=float)
        if self.eye == "link":
            last = self.segments[-1]
            position = position - last * np.array([np.cos(orientation), np.sin(orientation)])
            rest = self.segments[:-1]
            outer = float(sum(rest))
            inner = max(0.0, 2.0 * max(rest) - outer) if rest else 0.0
        else:
            outer, inner = self.reach, self.inner_reach
        radius = np.hypot(position[..., 0], position[..., 1])
        slack = 1e-9 * self.reach            # rounding of a pose the chain does reach
        return (radius <= outer + slack) & (radius >= inner - slack)

    def description(self, receptors: int) -> BodyDescription:
        return BodyDescription.revolute(self.n_joints, receptors, self.unit)

    def to_radians(self, motor: np.ndarray) -> np.ndarray:
        motor = np.asarray(motor, dtype=float)
        return motor if self.unit == "rad" else np.deg2rad(motor)

    def from_radians(self, angles: np.ndarray) -> np.ndarray:
        angles = np.asarray(angles, dtype=float)
        return angles if self.unit == "rad" else np.rad2deg(angles)

    def _check(self, motor: np.ndarray) -> np.ndarray:
        motor = np.asarray(motor, dtype=float)
        if motor.ndim == 0 or motor.shape[-1] != self.n_joints:
            raise ValueError(f"motor must have shape (..., {self.n_joints}), got {motor.shape}")
        return motor

    def forward(self, motor: np.ndarray) -> np.ndarray:
        """The eye's pose ``(..., 3)``; ``alpha`` unwrapped (``LEVEL_DIRECTION`` for a level eye)."""
        motor = self._check(motor)
        if self.is_paper:
            return forward(motor)
        angles = self.to_radians(motor)
        # Link by link, left to right: the order the compiled body adds in
        # (core.body), so both give the same bits.
        theta = np.zeros(motor.shape[:-1])
        pose = np.zeros(motor.shape[:-1] + (3,))
        for k, length in enumerate(self.segments):
            theta = theta + angles[..., k]
            pose[..., 0] += length * np.cos(theta)
            pose[..., 1] += length * np.sin(theta)
        pose[..., 2] = (LEVEL_DIRECTION if self.eye == "level"
                        else theta + angles[..., -1] if self.eye == "joint" else theta)
        return pose

    def jacobian(self, motor: np.ndarray) -> np.ndarray:
        """d pose / d motor, ``(..., 3, n_joints)``, per motor unit."""
        motor = self._check(motor)
        if self.is_paper:
            return jacobian(motor)
        angles = self.to_radians(motor)
        theta = np.cumsum(angles[..., :self.n_links], axis=-1)
        lengths = np.asarray(self.segments)
        tail_x = np.cumsum((lengths * np.cos(theta))[..., ::-1], axis=-1)[..., ::-1]
        tail_y = np.cumsum((lengths * np.sin(theta))[..., ::-1], axis=-1)[..., ::-1]
        jac = np.zeros(motor.shape[:-1] + (3, self.n_joints))
        jac[..., 0, :self.n_links] = -tail_y
        jac[..., 1, :self.n_links] = tail_x
        if self.eye != "level":
            jac[..., 2, :] = 1.0
        return jac * (np.pi / 180.0) if self.unit == "deg" else jac

    def pose_error(self, pose_a: np.ndarray, pose_b: np.ndarray) -> np.ndarray:
        """Distance of two poses, the orientation on the circle (0 for a level eye)."""
        return pose_error(pose_a, pose_b)


PAPER_ARM = Arm()
