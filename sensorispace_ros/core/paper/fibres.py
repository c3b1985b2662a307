"""The fibre of a sensor pose for any planar chain (``core.arm.Arm``): the
motor states that put the eye at one pose, from the chain's geometry.

A pose fixes the vector the *free links* add up to, the closing vector: for
an eye on a joint or a level eye every link must reach the eye's position
(an eye joint then takes up the orientation); for an eye fixed to its last
link, the last link points along the orientation and the links before it
reach its base. A fibre is thus the configuration space of a planar polygon,
the free links closed by that vector, with absolute link angles ``theta``.
Its dimension is the number of free links minus 2.

The functions of motor states work in radians, on an arm whose ``unit`` is
``"rad"`` (``points_of_view`` converts other units at its boundary); those
of poses and link lengths take any arm.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.arm import Arm, wrap_angle

TWO_PI = 2.0 * np.pi


def free_links(body_arm: Arm) -> np.ndarray:
    """Lengths of the links the pose leaves free (all but a link-fixed eye's last)."""
    segments = np.asarray(body_arm.segments, dtype=float)
    return segments[:-1] if body_arm.eye == "link" else segments


def closing_vector(body_arm: Arm, pose: np.ndarray) -> np.ndarray:
    """The vector ``(..., 2)`` the free links add up to at sensor pose ``pose`` ``(..., 3)``."""
    pose = np.asarray(pose, dtype=float)
    closing = pose[..., :2].copy()
    if body_arm.eye == "link":
        last = body_arm.segments[-1]
        closing[..., 0] -= last * np.cos(pose[..., 2])
        closing[..., 1] -= last * np.sin(pose[..., 2])
    return closing


def link_angles(body_arm: Arm, motor: np.ndarray) -> np.ndarray:
    """Absolute angles ``(..., k)`` of the free links of radian motor states."""
    motor = np.asarray(motor, dtype=float)
    return np.cumsum(motor[..., :len(free_links(body_arm))], axis=-1)


def motor_from_link_angles(body_arm: Arm, theta: np.ndarray, pose: np.ndarray,
                           reference: np.ndarray) -> np.ndarray:
    """Radian motor states with free-link angles ``theta`` ``(..., k)`` at
    ``pose`` (its orientation sets an eye joint or a link-fixed eye's last
    link), each joint taken within pi of ``reference`` ``(J,)``."""
    theta = np.asarray(theta, dtype=float)
    alpha = np.broadcast_to(np.asarray(pose, dtype=float)[..., 2], theta.shape[:-1])
    relative = np.diff(theta, axis=-1, prepend=0.0)
    if body_arm.eye == "level":
        motor = relative
    else:                                   # an eye joint or a link-fixed eye's last link
        motor = np.concatenate([relative, (alpha - theta[..., -1])[..., None]], axis=-1)
    reference = np.asarray(reference, dtype=float)
    return reference + wrap_angle(motor - reference)


def fibre_is_split(body_arm: Arm, pose: np.ndarray) -> np.ndarray:
    """Whether the fibre of ``pose`` has more than one connected piece.

    The planar polygon of side lengths ``l`` (the free links and the length
    of the closing vector) has a disconnected configuration space exactly
    when three of its sides are *long*: each two of them add up to more than
    half the perimeter (Kapovich and Millson 1995; for four sides it is
    Grashof's condition, and for the paper arm ``|tip| < 1``). The three
    longest sides are the ones to test. A triangle (0-D fibre) is "split"
    into its two mirror images whenever it is not flat.
    """
    links = free_links(body_arm)
    closing = np.linalg.norm(closing_vector(body_arm, pose), axis=-1)
    if len(links) < 2:
        return np.zeros(np.shape(closing), dtype=bool)
    sides = np.concatenate([np.broadcast_to(links, closing.shape + links.shape),
                            closing[..., None]], axis=-1)
    sides = -np.sort(-sides, axis=-1)
    half = 0.5 * sides.sum(axis=-1)
    return sides[..., 1] + sides[..., 2] > half


def two_link_angles(length_a: float, length_b: float, target: np.ndarray):
    """Both solutions of ``la e(ta) + lb e(tb) = target`` ``(..., 2)``.

    Returns ``(theta_a, theta_b, feasible)``: angle arrays ``(..., 2)`` (the
    two elbow branches) and ``(...)`` whether the target is within
    ``[|la - lb|, la + lb]``; infeasible entries hold the nearest (stretched
    or folded) configuration.
    """
    target = np.asarray(target, dtype=float)
    distance = np.hypot(target[..., 0], target[..., 1])
    heading = np.arctan2(target[..., 1], target[..., 0])
    feasible = (distance <= length_a + length_b) & (distance >= abs(length_a - length_b))
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_bend = (distance ** 2 + length_a ** 2 - length_b ** 2) / (2.0 * length_a * distance)
    bend = np.arccos(np.clip(np.nan_to_num(cos_bend, nan=1.0), -1.0, 1.0))
    theta_a = heading[..., None] + np.stack([bend, -bend], axis=-1)
    rest = target[..., None, :] - length_a * np.stack([np.cos(theta_a), np.sin(theta_a)], axis=-1)
    theta_b = np.arctan2(rest[..., 1], rest[..., 0])
    return theta_a, theta_b, feasible


def discrete_fibre(body_arm: Arm, motor: np.ndarray, *, tol: float = 1e-6) -> np.ndarray:
    """Every motor state ``(S, J)`` of a 0-D fibre: ``motor`` first, then the
    other solutions of its pose (the other elbow of a two-link chain),
    distinct from it by more than ``tol`` in the periodic motor metric and
    taken within pi of it per joint."""
    motor = np.asarray(motor, dtype=float)
    links = free_links(body_arm)
    if len(links) != 2:                     # one free link or none: the pose pins it
        return motor[None, :]
    pose = body_arm.forward(motor)
    first, second, _ = two_link_angles(links[0], links[1], closing_vector(body_arm, pose))
    theta = np.stack([first, second], axis=-1)                  # (2 branches, 2 links)
    solutions = motor_from_link_angles(body_arm, theta, pose, motor)
    found = [motor]
    for candidate in solutions:
        if all(_periodic_norm(candidate - kept) > tol for kept in found):
            found.append(candidate)
    return np.asarray(found)


def _periodic_norm(diff: np.ndarray) -> float:
    return float(np.linalg.norm(wrap_angle(diff)))
