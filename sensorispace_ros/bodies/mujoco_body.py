"""A MuJoCo model behind the body contract: motor states in, camera pixels out.

``MujocoBody`` answers ``sense(motor_states)`` with one image per row, each
pixel (each channel of it with ``mujoco.channels: rgb``) a receptor, as
uint8. Its description comes from the model: the commanded joints' names,
radians, a period of 2 pi each (a hinge turns once per 2 pi; a limited one
reaches no further than its range: a value beyond it lands at the limit,
and ``last_reached`` says so), the pixel count. The object is the model's
mocap body: ``set_lights`` places it and its geoms where the world's points
lie (the centre of the points, and each geom at its point: the world's
object, in the chain's frame, see ``bodies.mujoco_model``). Points that are
one of the world's arrangements turned (``world.rotation_count``) turn the
body (``object_turn``), so its geoms turn with it, headings included.

``settle``: ``kinematic`` puts the joints at the commanded values exactly;
``physics`` sends them to the model's position actuators and steps the
model until the joints stop (at most ``settle_steps`` steps), so the state
reached, and seen, is the physics' one. Poses (ground truth) are the
camera's, from MuJoCo's kinematics at the state reached.
"""
from __future__ import annotations

import copy
import time

import numpy as np

from sensorispace_ros.bodies.mujoco_model import MujocoSpec, PlanarChain, camera_pose
from sensorispace_ros.bodies.mujoco_render import TiledRenderer
from sensorispace_ros.config import ConfigError
from sensorispace_ros.core import world as world_mod
from sensorispace_ros.core.body_description import BodyDescription

SETTLE_SPEED = 1e-6        # rad/s: joints slower than this have settled


class MujocoBody:
    """The body of ``spec`` (``bodies.mujoco_model.MujocoSpec``) at ``motor_state``."""

    noise = None             # no imperfection beyond its pixels (core.imperfections)
    code = None

    def __init__(self, spec: MujocoSpec, chain: PlanarChain, cfg_mujoco: dict,
                 lights_world: np.ndarray | None = None, motor_state: np.ndarray | None = None,
                 layouts: list | None = None):
        import mujoco

        self.mujoco = mujoco
        self.spec, self.chain, self.arm = spec, chain, chain.arm
        # A copy of its own: the object's geoms move with this body's world only.
        self.model = copy.deepcopy(spec.model)
        self.data = mujoco.MjData(self.model)
        width, height = cfg_mujoco["image"]
        channels = 3 if cfg_mujoco["channels"] == "rgb" else 1
        self.renderer = TiledRenderer(self.model, spec.camera, width, height, channels,
                                      supersample=cfg_mujoco["supersample"],
                                      blur=cfg_mujoco["blur"])
        self.settle = cfg_mujoco["settle"]
        self.settle_steps = int(cfg_mujoco["settle_steps"])
        self.address = self.model.jnt_qposadr[list(spec.joints)]
        self.velocity_address = self.model.jnt_dofadr[list(spec.joints)]
        limited = self.model.jnt_limited[list(spec.joints)].astype(bool)
        ranges = self.model.jnt_range[list(spec.joints)]
        self.low = np.where(limited, ranges[:, 0], -np.inf)
        self.high = np.where(limited, ranges[:, 1], np.inf)
        self.actuators = _position_actuators(self.model, spec) if self.settle == "physics" else None
        self.n_motors = len(spec.joints)
        self.n_sensors = int(width * height * channels)
        self.description = BodyDescription(spec.joint_names, "rad",
                                           (2.0 * np.pi,) * self.n_motors, self.n_sensors)
        self.geom_z = self.model.geom_pos[list(spec.object_geoms), 2].copy()
        # The object's arrangements, unturned and about their centre: a placement that
        # is one of them turned turns the object's body (its geoms' headings with it).
        self.layouts = [np.asarray(o, dtype=float) - np.mean(o, axis=0) for o in layouts or ()]
        self.queries = 0          # motor states probed so far
        self.calls = 0            # sense() and move() calls
        self.changes = 0          # set_lights() calls: the number of the current layout
        self.last_reached: np.ndarray | None = None
        self.render_seconds = 0.0
        self.lights_world = None
        if lights_world is not None:
            self.set_lights(lights_world, change=0)
        self.motor_state = None if motor_state is None else np.asarray(motor_state, float)
        if self.motor_state is not None and self.settle == "physics":
            self.motor_state = self._settle_at(self.motor_state)

    def set_lights(self, lights_world: np.ndarray, change: int | None = None) -> None:
        """The object at the world's points ``(L, 2)`` (chain frame): one per geom of it."""
        points = np.asarray(lights_world, dtype=float).reshape(-1, 2)
        if len(points) != len(self.spec.object_geoms):
            raise ValueError(f"the object has {len(self.spec.object_geoms)} geoms, "
                             f"got {len(points)} points")
        world = self.chain.to_world_xy(points)
        centre = world.mean(axis=0)
        turn = object_turn(points, self.layouts)
        mocap = self.spec.mocap
        self.data.mocap_pos[mocap, :2] = centre
        self.data.mocap_quat[mocap] = (np.cos(turn / 2), 0.0, 0.0, np.sin(turn / 2))
        # The geoms about the body's centre, unturned: the body's turn places them.
        offsets = world - centre
        if turn != 0.0:
            offsets = offsets @ world_mod.rotation_matrix(turn)
        self.model.geom_pos[list(self.spec.object_geoms), :2] = offsets
        self.model.geom_pos[list(self.spec.object_geoms), 2] = self.geom_z
        self.lights_world = points
        self.changes = self.changes + 1 if change is None else int(change)

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        return self.sense_with_poses(motor_states)[0]

    def sense_with_poses(self, motor_states: np.ndarray, call: int | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Images ``(B, receptors)`` uint8 and the camera poses ``(B, 3)`` (chain
        frame) of the states reached."""
        if self.lights_world is None:
            raise RuntimeError("MujocoBody.sense called before the object was placed")
        reached = self._count(motor_states)
        return self._look(reached)

    def sense_at_rest(self, kernel: str | None = None, change: int | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
        """What the resting camera sees ``(R,)`` and its pose ``(3,)``: no query."""
        if self.lights_world is None or self.motor_state is None:
            raise RuntimeError("MujocoBody.sense_at_rest needs the object and a motor state")
        images, poses = self._look(self.motor_state[None])
        return images[0], poses[0]

    def resting_truth(self) -> np.ndarray | None:
        """``sense_at_rest``'s image as floats (ground truth; the pixels have no
        noise of their own); None before the arm rests anywhere."""
        if self.lights_world is None or self.motor_state is None:
            return None
        return self.sense_at_rest()[0].astype(float)

    def physics_state(self) -> np.ndarray:
        """What the next settle steps from, as a vector (MuJoCo's
        ``mjSTATE_INTEGRATION``: joints, speeds, controls, warm start...);
        empty with ``settle: kinematic``, whose answers depend on the command
        alone."""
        state = np.empty(self._physics_size())
        if len(state):
            self.mujoco.mj_getState(self.model, self.data, state, _integration_state(self.mujoco))
        return state

    def set_physics_state(self, state: np.ndarray) -> None:
        """Stand where ``physics_state`` stood: the same commands from here are
        answered bit for bit as they were from there."""
        state = np.asarray(state, dtype=float).reshape(-1)
        size = self._physics_size()
        if len(state) != size:
            raise ValueError(f"physics state: need {size} values, got {len(state)}")
        if size:
            self.mujoco.mj_setState(self.model, self.data, state, _integration_state(self.mujoco))

    def _physics_size(self) -> int:
        """Values of ``physics_state``: 0 with ``settle: kinematic``."""
        if self.settle != "physics":
            return 0
        return int(self.mujoco.mj_stateSize(self.model, _integration_state(self.mujoco)))

    def move(self, motor_states: np.ndarray, call: int | None = None) -> None:
        """The command ``sense`` answers, without the images."""
        self._count(motor_states)

    def sensor_pose(self, motor_states: np.ndarray) -> np.ndarray:
        """The camera's pose (chain frame) at ``motor_states`` (ground truth)."""
        return self.arm.forward(np.clip(np.asarray(motor_states, float), self.low, self.high))

    def _count(self, motor_states) -> np.ndarray:
        motor_states = np.asarray(motor_states, dtype=float)
        if motor_states.ndim != 2 or motor_states.shape[1] != self.n_motors:
            raise ValueError(f"motor_states must have shape (B, {self.n_motors}), "
                             f"got {motor_states.shape}")
        self.queries += len(motor_states)
        self.calls += 1
        reached = np.clip(motor_states, self.low, self.high)
        if self.settle == "physics":
            reached = np.array([self._settle_at(row) for row in reached]).reshape(reached.shape)
        self.last_reached = reached
        if len(reached):
            self.motor_state = reached[-1].copy()
        return reached

    def _settle_at(self, target: np.ndarray) -> np.ndarray:
        """Drive the position actuators to ``target`` and step until the joints stop."""
        mujoco, model, data = self.mujoco, self.model, self.data
        data.ctrl[self.actuators] = target
        for _ in range(self.settle_steps):
            mujoco.mj_step(model, data)
            if np.max(np.abs(data.qvel[self.velocity_address])) < SETTLE_SPEED:
                break
        return data.qpos[self.address].copy()

    def _look(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mujoco, model, data = self.mujoco, self.model, self.data
        poses = np.empty((len(states), 3))
        saved = data.qpos[self.address].copy()

        def pose_row(i):
            data.qpos[self.address] = states[i]
            mujoco.mj_kinematics(model, data)
            mujoco.mj_camlight(model, data)
            poses[i] = camera_pose(data, self.spec.camera)

        started = time.perf_counter()
        images = self.renderer.render(data, len(states), pose_row)
        self.render_seconds += time.perf_counter() - started
        if self.settle == "physics":
            data.qpos[self.address] = saved
        return images.reshape(len(states), -1), self.chain.to_chain(poses)


def _integration_state(mujoco):
    """MuJoCo's state of what stepping reads (``mjSTATE_INTEGRATION``)."""
    return mujoco.mjtState.mjSTATE_INTEGRATION


def _position_actuators(model, spec: MujocoSpec) -> list[int]:
    """The position actuator of each commanded joint (``mujoco.settle: physics``)."""
    import mujoco

    found = []
    for joint, name in zip(spec.joints, spec.joint_names):
        ids = [a for a in range(model.nu)
               if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
               and model.actuator_trnid[a, 0] == joint and model.actuator_biastype[a] != 0]
        if not ids:
            raise ConfigError(f"mujoco.settle: physics needs a position actuator on every "
                              f"commanded joint; joint {name!r} has none")
        found.append(ids[0])
    return found


# A placement is a turned arrangement when it lies this close to it (relative to its size).
_RIGID_TOL = 1e-9


def object_turn(points: np.ndarray, layouts: list) -> float:
    """The turn (rad, about the object's centre) that carries one of the
    ``layouts`` (unturned, about their centre) onto ``points`` ``(L, 2)``, a
    rigid placement of it (2-D Procrustes); 0 when none fits."""
    q = np.asarray(points, dtype=float) - np.mean(points, axis=0)
    for layout in layouts:
        if layout.shape != q.shape:
            continue
        turn = float(np.arctan2(np.sum(layout[:, 0] * q[:, 1] - layout[:, 1] * q[:, 0]),
                                np.sum(layout[:, 0] * q[:, 0] + layout[:, 1] * q[:, 1])))
        placed = layout @ world_mod.rotation_matrix(turn).T
        if np.max(np.abs(placed - q)) <= _RIGID_TOL * (1.0 + np.max(np.abs(q))):
            return 0.0 if abs(turn) <= _RIGID_TOL else turn
    return 0.0
