"""Drawing pieces shared by the figures: the colour code of a sensor position,
arms, POV loops in motor space, panels, segments and paths in 2-D or 3-D."""
from __future__ import annotations

import json
from typing import Mapping

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.colors import hsv_to_rgb, to_rgb  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection  # noqa: E402

from sensorispace_ros.core import arm  # noqa: E402

TWO_PI = 2.0 * np.pi
DPI = 110
PAIR_COLOURS = ("#1f77b4", "#d62728", "#2ca02c")       # three examples: blue, red, green
ARM_REACH = 3.0
ARM_HOLE = 1.0                                          # |tip| < 1: POV splits in two loops


def position_colours(positions: np.ndarray) -> np.ndarray:
    """RGB ``(P, 3)``: hue = angle of the sensor around the base, saturation = radius."""
    positions = np.asarray(positions, dtype=float)
    angle = np.arctan2(positions[:, 1], positions[:, 0])
    radius = np.hypot(positions[:, 0], positions[:, 1])
    hue = (angle + np.pi) / TWO_PI
    saturation = 0.25 + 0.75 * np.clip((radius - ARM_HOLE) / (ARM_REACH - ARM_HOLE), 0.0, 1.0)
    value = np.full_like(hue, 0.9)
    return hsv_to_rgb(np.stack([hue, saturation, value], axis=-1))


def arm_points(motor: np.ndarray) -> np.ndarray:
    """Base, elbow joints and tip of the arm, ``(..., 4, 2)``."""
    theta = np.cumsum(np.asarray(motor, dtype=float)[..., :3], axis=-1)
    steps = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    zero = np.zeros(steps.shape[:-2] + (1, 2))
    return np.concatenate([zero, np.cumsum(steps, axis=-2)], axis=-2)


def draw_arms(ax, motors: np.ndarray, colours, linewidth: float = 0.8, alpha: float = 1.0,
              eye_length: float = 0.25) -> None:
    """Arms as polylines with the eye's optical axis as a short tick at the tip."""
    motors = np.atleast_2d(motors)
    points = arm_points(motors)
    colours = np.broadcast_to(np.asarray(to_rgb(colours) if isinstance(colours, str)
                                         else colours, dtype=float), (len(motors), 3))
    ax.add_collection(LineCollection(points, colors=colours, linewidths=linewidth, alpha=alpha))
    pose = arm.forward(motors)
    axis = np.stack([pose[:, :2], pose[:, :2] + eye_length * np.stack(
        [np.cos(pose[:, 2]), np.sin(pose[:, 2])], axis=-1)], axis=1)
    ax.add_collection(LineCollection(axis, colors=colours, linewidths=linewidth * 2.5,
                                     alpha=alpha))
    ax.plot([0], [0], marker="s", color="k", markersize=5)


def centred_loop(samples: np.ndarray) -> np.ndarray:
    """Shift each joint of a POV by a multiple of 2 pi so its mean lies in [-pi, pi).

    A whole POV is a closed loop in unwrapped coordinates; shifting (not
    wrapping) keeps it one unbroken curve while putting all POVs in one box.
    """
    samples = np.asarray(samples, dtype=float)
    shift = TWO_PI * np.round(samples.mean(axis=-2, keepdims=True) / TWO_PI)
    return samples - shift


def closed(samples: np.ndarray) -> np.ndarray:
    return np.concatenate([samples, samples[..., :1, :]], axis=-2)


def wrapped_path(motor: np.ndarray) -> np.ndarray:
    """Motor path wrapped to [-pi, pi) with NaN rows where a joint jumps by
    2 pi, so a plot shows the jump as a gap instead of a line across the box."""
    motor = np.asarray(motor, dtype=float)
    wrapped = arm.wrap_angle(motor)
    jump = np.any(np.abs(np.diff(wrapped, axis=0)) > np.pi, axis=1)
    rows = []
    for k, row in enumerate(wrapped):
        if k and jump[k - 1]:
            rows.append(np.full(motor.shape[1], np.nan))
        rows.append(row)
    return np.asarray(rows)


def scatter_points(ax, points: np.ndarray, colours, size: float = 8.0, **kwargs) -> None:
    points = np.asarray(points)
    if points.shape[1] == 3:
        ax.scatter(points[:, 0], points[:, 1], points[:, 2], c=colours, s=size,
                   depthshade=False, linewidths=0, **kwargs)
    else:
        ax.scatter(points[:, 0], points[:, 1], c=colours, s=size, linewidths=0, **kwargs)


def panel_axes(fig, position, dim: int, title: str):
    ax = fig.add_subplot(position, projection="3d" if dim == 3 else None)
    ax.set_title(title, fontsize=10)
    if dim == 2:
        ax.set_aspect("equal", adjustable="datalim")
    else:
        ax.tick_params(labelsize=7)
    return ax


def equal_3d(ax, points: np.ndarray) -> None:
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre, half = (lo + hi) / 2.0, (hi - lo).max() / 2.0 or 1.0
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))


def face_on(ax, points: np.ndarray) -> None:
    """Look at a (nearly planar) 3-D curve along its least-spread direction,
    so a loop is seen as a loop rather than edge-on."""
    centred = points - points.mean(axis=0)
    normal = np.linalg.svd(centred, full_matrices=False)[2][-1]
    if normal[2] < 0:
        normal = -normal
    # Tilted a little off the normal so the 3-D axes stay readable.
    ax.view_init(elev=float(np.degrees(np.arcsin(np.clip(normal[2], -1, 1)))) * 0.8 + 8.0,
                 azim=float(np.degrees(np.arctan2(normal[1], normal[0]))))


def motor_axes(ax) -> None:
    ax.set_xlabel("m1 (rad)", fontsize=8)
    ax.set_ylabel("m2 (rad)", fontsize=8)
    ax.set_zlabel("m3 (rad)", fontsize=8)
    ax.tick_params(labelsize=7)


def segments_of(points: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    return np.stack([points[pairs[:, 0]], points[pairs[:, 1]]], axis=1)


def add_segments(ax, segments: np.ndarray, colour, linewidth: float = 0.8,
                  alpha: float = 1.0) -> None:
    if segments.shape[-1] == 3:
        ax.add_collection3d(Line3DCollection(segments, colors=colour, linewidths=linewidth,
                                             alpha=alpha))
    else:
        ax.add_collection(LineCollection(segments, colors=colour, linewidths=linewidth,
                                         alpha=alpha))


def plot_path(ax, points: np.ndarray, colour, linewidth: float = 1.5, **kwargs) -> None:
    if points.shape[1] == 3:
        ax.plot(points[:, 0], points[:, 1], points[:, 2], color=colour, linewidth=linewidth,
                **kwargs)
    else:
        ax.plot(points[:, 0], points[:, 1], color=colour, linewidth=linewidth, **kwargs)


def lighter(colour, amount: float = 0.6):
    rgb = np.asarray(to_rgb(colour))
    return tuple(rgb + (1.0 - rgb) * amount)


def run_config(arrays: Mapping) -> dict:
    return json.loads(str(arrays["config_json"]))


def grid_transitions(positions: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """POV index pairs one grid step apart: (horizontal ``(H, 2)``, vertical ``(V, 2)``).

    By distance, not by rounding to a lattice: the initial POV sits half a
    cell off the others' lattice and must get no transition.
    """
    from scipy.spatial import cKDTree

    positions = np.asarray(positions, dtype=float)
    pairs = cKDTree(positions).query_pairs(1.01 * spacing, output_type="ndarray")
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    step = positions[pairs[:, 1]] - positions[pairs[:, 0]]
    exact = np.abs(np.hypot(*step.T) - spacing) < 0.01 * spacing
    horizontal = exact & (np.abs(step[:, 1]) < 0.01 * spacing)
    vertical = exact & (np.abs(step[:, 0]) < 0.01 * spacing)
    return pairs[horizontal], pairs[vertical]
