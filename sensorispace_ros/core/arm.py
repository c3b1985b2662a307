"""Planar serial arm: three unit segments, four hinge joints (paper Sec. 2.3).

Joints 1-3 orient the segments relative to the previous one; joint 4 rotates
the eye at the tip. The sensor pose is ``(x_tip, y_tip, alpha_tip)``.
All functions broadcast over leading axes: ``motor`` has shape ``(..., 4)``.
"""
from __future__ import annotations

import numpy as np

N_JOINTS = 4
SEGMENT_LENGTHS = (1.0, 1.0, 1.0)


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
    # One joint per row: the sums run as whole-row additions. numpy's cumsum /
    # sum over a short last axis loop per batch row (0.12 ms for 649 rows vs
    # 0.05 ms here) and add left to right, which these additions repeat, so
    # the bits are the same (tests/core/test_body_simulation.py).
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
