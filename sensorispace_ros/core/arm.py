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
    theta = _segment_angles(motor)
    lengths = np.asarray(lengths, dtype=float)
    x = np.sum(lengths * np.cos(theta), axis=-1)
    y = np.sum(lengths * np.sin(theta), axis=-1)
    alpha = np.sum(motor, axis=-1)
    return np.stack([x, y, alpha], axis=-1)


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
