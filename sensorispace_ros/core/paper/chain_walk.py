"""The kernel walk's step for any planar chain with 1-D points of view
(paper Sec. 4.1), and the least-norm Newton projection onto a pose.

A 1-D fibre's Jacobian has one more column than its rank: 3 x 4 for three
links and an eye joint (or four links and a link-fixed eye), 2 x 3 for three
links and a level eye (its orientation row is zero and left out). The kernel
is the vector of the signed maximal minors of the ``r x (r + 1)`` Jacobian
(for r = 2 the cross product of its rows): it varies continuously along the
walk, where an SVD null vector flips sign. ``points_of_view`` runs the paper
arm through its own closed-form step; this one takes any radian ``Arm``.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.arm import Arm


def pose_rows(body_arm: Arm) -> slice:
    """The rows of pose and Jacobian that constrain the eye (no orientation
    for a level eye)."""
    return slice(0, 2) if body_arm.eye == "level" else slice(0, 3)


def kernel_step(body_arm: Arm):
    """``step(m, pose_target) -> (corrected m, unit kernel)`` for joint-major
    radian motor states ``m`` ``(J, n)`` and poses ``(3, n)``: one least-norm
    Newton correction onto the pose, and the kernel of the Jacobian taken
    before it (as the paper arm's step does)."""
    if body_arm.unit != "rad" or body_arm.pov_dim != 1:
        raise ValueError(f"the kernel walk needs a radian arm with 1-D points of view, "
                         f"got {body_arm}")
    lengths = np.asarray(body_arm.segments, dtype=float)[:, None]
    n_links, eye = body_arm.n_links, body_arm.eye

    def step(m: np.ndarray, pose_target: np.ndarray):
        theta = np.cumsum(m[:n_links], axis=0)
        tail_x = np.cumsum((lengths * np.cos(theta))[::-1], axis=0)[::-1]
        tail_y = np.cumsum((lengths * np.sin(theta))[::-1], axis=0)[::-1]
        rows = [np.zeros_like(m), np.zeros_like(m)]
        rows[0][:n_links], rows[1][:n_links] = -tail_y, tail_x
        residual = [tail_x[0] - pose_target[0], tail_y[0] - pose_target[1]]
        if eye != "level":
            # The walk is continuous in unwrapped angles: no wrapping needed.
            rows.append(np.ones_like(m))
            residual.append((m.sum(axis=0) if eye == "joint" else theta[-1]) - pose_target[2])
        jac = np.moveaxis(np.stack(rows), -1, 0)                  # (n, r, J)
        kernel = signed_minors(jac)
        kernel /= np.linalg.norm(kernel, axis=-1, keepdims=True)
        gram = jac @ np.swapaxes(jac, -1, -2)
        coeff = np.linalg.solve(gram, np.stack(residual, axis=-1)[..., None])
        correction = (np.swapaxes(jac, -1, -2) @ coeff)[..., 0]
        return m - correction.T, kernel.T

    return step


def signed_minors(jac: np.ndarray) -> np.ndarray:
    """Null vector ``(..., r + 1)`` of ``(..., r, r + 1)`` matrices: entry c
    is ``(-1)^c`` times the minor without column c."""
    jac = np.asarray(jac, dtype=float)
    columns = jac.shape[-1]
    if jac.shape[-2] != columns - 1:
        raise ValueError(f"signed minors need r x (r + 1) matrices, got {jac.shape}")
    keep = [[k for k in range(columns) if k != c] for c in range(columns)]
    return np.stack([(-1.0) ** c * np.linalg.det(jac[..., :, cols])
                     for c, cols in enumerate(keep)], axis=-1)


def project_onto_pose(motor: np.ndarray, target_pose: np.ndarray, body_arm: Arm, *,
                      tol: float = 1e-12, max_iter: int = 50):
    """Newton-project motor states ``(P, S, J)`` onto the poses ``(P, 3)`` of
    ``body_arm``: least-norm corrections ``-J^+ r`` (across the fibre, not
    along it). Returns the states and each one's pose error ``(P, S)``."""
    rows = pose_rows(body_arm)
    motor = np.array(motor, dtype=float, copy=True)
    target = np.broadcast_to(np.asarray(target_pose, float)[:, None, :], motor.shape[:-1] + (3,))
    for _ in range(max_iter):
        residual = pose_residual(body_arm.forward(motor), target)[..., rows]
        if np.linalg.norm(residual, axis=-1).max(initial=0.0) <= tol:
            break
        motor -= least_norm_solve(body_arm.jacobian(motor)[..., rows, :], residual)
    return motor, body_arm.pose_error(body_arm.forward(motor), target)


def pose_residual(pose: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``pose - target``, the orientation wrapped to [-pi, pi)."""
    diff = pose - target
    diff[..., 2] = (diff[..., 2] + np.pi) % (2.0 * np.pi) - np.pi
    return diff


def least_norm_solve(jac: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """``J^+ r = J^T (J J^T)^-1 r`` for full-row-rank ``(..., r, J)`` Jacobians."""
    gram = jac @ np.swapaxes(jac, -1, -2)
    coeff = np.linalg.solve(gram, residual[..., None])
    return (np.swapaxes(jac, -1, -2) @ coeff)[..., 0]
