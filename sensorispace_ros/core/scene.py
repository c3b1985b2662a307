"""What the viewer draws, as plain geometry: the arm, its eye, the lights, the
points of view found, and colours for the representation. No ROS here: the
viewer node (graph.nodes.viewer) turns these shapes into markers and clouds
(messages.shapes_to_marker_array, messages.coloured_cloud).

Everything is in the world frame of the arm (arm units, z = 0: the arm is
planar). The eye is drawn as the rays of its pinhole retina (unit focal
length, core.retina): the two edges of the retina and one ray per receptor.
The representation is coloured by the true position of each point of view,
so a map that preserves the neighbourhoods of space shows a smooth gradient.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensorispace_ros.core import arm

WORLD_FRAME = "world"
REPRESENTATION_FRAME = "representation"

# RGBA of each kind of shape (what Foxglove and RViz draw them in).
ARM_COLOUR = (0.75, 0.75, 0.78, 1.0)
JOINT_COLOUR = (0.20, 0.45, 0.90, 1.0)
EYE_COLOUR = (1.00, 0.55, 0.10, 0.9)
RECEPTOR_COLOUR = (1.00, 0.80, 0.30, 0.5)
LIGHT_COLOUR = (1.00, 0.95, 0.20, 1.0)
POV_COLOUR = (0.20, 0.80, 0.40, 0.9)
PROBE_COLOUR = (0.90, 0.30, 0.80, 0.8)
UNKNOWN_POSITION_COLOUR = (0.5, 0.5, 0.5)

LINE_STRIP, LINE_LIST, SPHERES, POINTS = "line_strip", "line_list", "spheres", "points"
KINDS = (LINE_STRIP, LINE_LIST, SPHERES, POINTS)


@dataclass(frozen=True)
class Shape:
    """One drawable: ``points`` (n, 3) joined as ``kind`` says; ``size`` is the
    line width or the sphere / point diameter (arm units)."""
    namespace: str
    kind: str
    points: np.ndarray
    size: float
    colour: tuple

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"kind: must be one of {', '.join(KINDS)}, got {self.kind!r}")
        points = np.asarray(self.points, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points: must have shape (n, 3), got {points.shape}")
        if self.kind == LINE_LIST and len(points) % 2:
            raise ValueError(f"points: a line list needs pairs, got {len(points)} points")


def _planar(xy: np.ndarray) -> np.ndarray:
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    return np.column_stack([xy, np.zeros(len(xy))])


def arm_joint_positions(motor_state: np.ndarray, body_arm: arm.Arm = arm.PAPER_ARM
                        ) -> np.ndarray:
    """The base, the elbows and the tip (where the eye sits) of the planar
    chain ``body_arm``: ``(links + 1, 2)``. The tip is ``body_arm.forward``'s (x, y)."""
    motor_state = np.asarray(motor_state, dtype=float).reshape(-1)
    if motor_state.shape != (body_arm.n_joints,):
        raise ValueError(f"motor_state: must hold {body_arm.n_joints} joint angles, "
                         f"got shape {motor_state.shape}")
    theta = np.cumsum(body_arm.to_radians(motor_state)[:body_arm.n_links])
    steps = np.asarray(body_arm.segments, dtype=float)[:, None] * np.column_stack(
        [np.cos(theta), np.sin(theta)])
    return np.vstack([np.zeros((1, 2)), np.cumsum(steps, axis=0)])


def eye_rays(pose: np.ndarray, directions_on_retina: np.ndarray, length: float) -> np.ndarray:
    """Segments (2 k, 2) from the eye at ``pose`` (x, y, alpha) through retina
    positions ``directions_on_retina`` (unit focal length), each ``length`` long."""
    x, y, alpha = np.asarray(pose, dtype=float).reshape(3)
    angles = alpha + np.arctan(np.asarray(directions_on_retina, dtype=float).reshape(-1))
    ends = np.column_stack([x + length * np.cos(angles), y + length * np.sin(angles)])
    starts = np.broadcast_to([x, y], ends.shape)
    return np.stack([starts, ends], axis=1).reshape(-1, 2)


def position_colours(xy: np.ndarray) -> np.ndarray:
    """RGB in [0, 1] of 2-D positions: red grows with x, green with y, over the
    span of ``xy`` (the same scheme for every map of the same positions)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if not len(xy):
        return np.zeros((0, 3))
    low, span = xy.min(axis=0), np.ptp(xy, axis=0)
    unit = (xy - low) / np.where(span > 0, span, 1.0)
    return np.column_stack([unit[:, 0], unit[:, 1], 1.0 - 0.5 * (unit[:, 0] + unit[:, 1])])


class Scene:
    """The world as the viewer last heard of it, and the shapes that draw it.

    ``receptors`` (retina positions, unit focal length), ``retina_half_width``
    and ``body_arm`` (the planar chain that carries the eye) come from the
    run's world; ``ray_length`` is how far the eye's rays are drawn.
    """

    def __init__(self, receptors: np.ndarray, retina_half_width: float, ray_length: float,
                 body_arm: arm.Arm = arm.PAPER_ARM):
        if not retina_half_width > 0 or not ray_length > 0:
            raise ValueError(f"retina_half_width and ray_length must be > 0, got "
                             f"{retina_half_width} and {ray_length}")
        self.receptors = np.asarray(receptors, dtype=float).reshape(-1)
        self.retina_half_width = float(retina_half_width)
        self.ray_length = float(ray_length)
        self.arm = body_arm
        self.lights: np.ndarray | None = None          # (L, 2)
        self.motor_state: np.ndarray | None = None     # the arm at rest, (joints,)
        self.probes = np.zeros((0, 3))                  # eye poses of the latest command
        self.pov_positions: dict[int, np.ndarray] = {}  # true (x, y) of each POV found

    def set_lights(self, lights: np.ndarray) -> None:
        self.lights = np.asarray(lights, dtype=float).reshape(-1, 2).copy()

    def set_motor_state(self, motor_state: np.ndarray) -> None:
        motor_state = np.asarray(motor_state, dtype=float).reshape(-1)
        if motor_state.shape != (self.arm.n_joints,):
            raise ValueError(f"motor_state: must hold {self.arm.n_joints} joint angles, "
                             f"got shape {motor_state.shape}")
        self.motor_state = motor_state.copy()

    def set_probes(self, poses: np.ndarray) -> None:
        self.probes = np.asarray(poses, dtype=float).reshape(-1, 3).copy()

    def add_points_of_view(self, ids: np.ndarray, motor_states: np.ndarray) -> None:
        """POVs ``ids`` with one motor state each (any of the POV's samples: they
        share the eye's position)."""
        positions = self.arm.forward(
            np.asarray(motor_states, dtype=float).reshape(-1, self.arm.n_joints))
        for pov, position in zip(np.asarray(ids).reshape(-1), positions):
            self.pov_positions[int(pov)] = position[:2].copy()

    def shapes(self) -> list[Shape]:
        """Every shape there is something to draw for (none before the first news)."""
        shapes = []
        if self.motor_state is not None:
            joints = _planar(arm_joint_positions(self.motor_state, self.arm))
            pose = self.arm.forward(self.motor_state)
            edges = self.retina_half_width * np.array([-1.0, 1.0])
            shapes += [
                Shape("arm", LINE_STRIP, joints, 0.06, ARM_COLOUR),
                Shape("joints", SPHERES, joints, 0.14, JOINT_COLOUR),
                Shape("field_of_view", LINE_LIST,
                      _planar(eye_rays(pose, edges, self.ray_length)), 0.03, EYE_COLOUR),
                Shape("receptors", LINE_LIST,
                      _planar(eye_rays(pose, self.receptors, self.ray_length)), 0.01,
                      RECEPTOR_COLOUR),
            ]
        if self.lights is not None and len(self.lights):
            shapes.append(Shape("lights", SPHERES, _planar(self.lights), 0.25, LIGHT_COLOUR))
        if self.pov_positions:
            positions = np.array([self.pov_positions[k] for k in sorted(self.pov_positions)])
            shapes.append(Shape("points_of_view", SPHERES, _planar(positions), 0.08, POV_COLOUR))
        if len(self.probes):
            shapes.append(Shape("probes", POINTS, _planar(self.probes[:, :2]), 0.04,
                                PROBE_COLOUR))
        return shapes

    def representation_colours(self, pov_ids: np.ndarray) -> np.ndarray:
        """RGB in [0, 1] of each POV of an embedding, by its true position among
        those known (grey for a POV the viewer has not seen)."""
        pov_ids = np.asarray(pov_ids).reshape(-1)
        known = sorted(self.pov_positions)
        colours = np.tile(UNKNOWN_POSITION_COLOUR, (len(pov_ids), 1))
        if not known:
            return colours
        by_id = dict(zip(known, position_colours(np.array([self.pov_positions[k]
                                                           for k in known]))))
        for row, pov in enumerate(pov_ids):
            if int(pov) in by_id:
                colours[row] = by_id[int(pov)]
        return colours
