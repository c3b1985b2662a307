"""Compensation search, the paper's analytic shortcut (paper Sec. 4.2,
"Compensation").

Analytic, not naive: it uses the forward model f and the object's known
displacement. The compensating motor state minimises
``||f(m) - [x_tip + dx_obj, y_tip + dy_obj, alpha_tip]||^2`` by Nelder-Mead,
and counts as a compensation iff the error *norm* is at most xi = 1e-3
(the squared error would admit targets just beyond reach). Any planar chain
(``core.arm.Arm``): the search runs in the arm's motor unit, and the
orientation counts only where the pose has one (not for a level eye).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize

from sensorispace_ros.core import arm
from sensorispace_ros.core.arm import PAPER_ARM, Arm

TWO_PI = 2.0 * math.pi


def compensate_pose(motor_start: np.ndarray, target_pose: np.ndarray, *,
                    threshold: float = 1e-3, initial_simplex_size: float = 0.25,
                    xatol: float = 1e-6, fatol: float = 1e-14, maxiter: int = 2000,
                    body_arm: Arm = PAPER_ARM):
    """Nelder-Mead from ``motor_start`` towards the sensor pose ``target_pose``
    of ``body_arm`` (the paper arm by default).

    Returns ``(motor (J,), error, success)`` with ``error`` the pose error
    norm at the optimum (orientation wrapped) and ``success = error <=
    threshold``. ``motor`` is unwrapped, continuous with ``motor_start``.

    ``initial_simplex_size``: scipy's default simplex (5 % of each
    coordinate) gets stuck once the arm is stretched; a simplex of ~0.25 rad
    around the start does not; it is given in radians and converted to the
arm's motor unit, as is ``xatol``. ``xatol``/``fatol``
    stop the search once the simplex has collapsed: ``fatol = 1e-14`` on the
    squared error means a compensation lands ~1e-7 from its target, so
    anchoring later targets on it does not accumulate error over ~650
    compensations.
    """
    start = np.asarray(motor_start, dtype=float)
    target = np.asarray(target_pose, dtype=float)
    joints = body_arm.n_joints
    if start.shape != (joints,) or not np.all(np.isfinite(start)):
        raise ValueError(f"motor_start must be a finite ({joints},) vector, got {start}")
    if target.shape != (3,) or not np.all(np.isfinite(target)):
        raise ValueError(f"target_pose must be a finite (3,) pose, got {target}")
    if not threshold > 0:
        raise ValueError(f"threshold must be > 0, got {threshold}")
    if not initial_simplex_size > 0:
        raise ValueError(f"initial_simplex_size must be > 0, got {initial_simplex_size}")
    if int(maxiter) != maxiter or maxiter < 1:
        raise ValueError(f"maxiter must be a positive integer, got {maxiter}")

    if body_arm.is_paper:
        objective = _squared_pose_error(target)
    else:
        objective = _chain_squared_pose_error(body_arm, target)
        initial_simplex_size = float(body_arm.from_radians(initial_simplex_size))
        xatol = float(body_arm.from_radians(xatol))
    simplex = np.vstack([start, start + initial_simplex_size * np.eye(joints)])
    result = minimize(objective, start, method="Nelder-Mead",
                      options={"initial_simplex": simplex, "xatol": xatol, "fatol": fatol,
                               "maxiter": int(maxiter), "maxfev": 2 * int(maxiter)})
    motor = np.asarray(result.x, dtype=float)
    pose = body_arm.forward(motor)
    if body_arm.eye == "level":          # a level eye's pose has no orientation to match
        error = float(np.hypot(pose[0] - target[0], pose[1] - target[1]))
    else:
        error = float(body_arm.pose_error(pose, target))
    return motor, error, error <= threshold


def _squared_pose_error(target: np.ndarray):
    """``||f(m) - target||^2`` (orientation wrapped) for one motor vector.

    Written with ``math`` for the three unit segments of ``arm``: Nelder-Mead
    calls it a few hundred times per event, and on a single motor vector the
    batched numpy ``arm.forward`` costs many times more (docs/benchmarks.md).
    Tested against ``arm.forward``.
    """
    if arm.SEGMENT_LENGTHS != (1.0, 1.0, 1.0):
        raise ValueError("the compensation objective assumes unit segments")
    tx, ty, ta = (float(v) for v in target)
    cos, sin = math.cos, math.sin

    def objective(motor: np.ndarray) -> float:
        m0, m1, m2, m3 = motor.tolist()
        t1 = m0 + m1
        t2 = t1 + m2
        dx = cos(m0) + cos(t1) + cos(t2) - tx
        dy = sin(m0) + sin(t1) + sin(t2) - ty
        da = (t2 + m3 - ta + math.pi) % TWO_PI - math.pi
        return dx * dx + dy * dy + da * da

    return objective


def _chain_squared_pose_error(body_arm: Arm, target: np.ndarray):
    """``||f(m) - target||^2`` of any chain, for one motor vector in its unit:
    the position always, the orientation (wrapped) unless the eye is level.
    ``math`` on a Python list, like ``_squared_pose_error``."""
    tx, ty, ta = (float(v) for v in target)
    lengths = tuple(float(v) for v in body_arm.segments)
    scale = float(body_arm.to_radians(1.0))
    n_links, eye = len(lengths), body_arm.eye
    cos, sin = math.cos, math.sin

    def objective(motor: np.ndarray) -> float:
        values = motor.tolist()
        theta = x = y = 0.0
        for k in range(n_links):
            theta += values[k] * scale
            x += lengths[k] * cos(theta)
            y += lengths[k] * sin(theta)
        dx, dy = x - tx, y - ty
        if eye == "level":
            return dx * dx + dy * dy
        alpha = theta + values[-1] * scale if eye == "joint" else theta
        da = (alpha - ta + math.pi) % TWO_PI - math.pi
        return dx * dx + dy * dy + da * da

    return objective
