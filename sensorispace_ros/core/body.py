"""The body as the naive agent meets it: motor states in, sensations out.

``SensingBody`` is the whole interface the naive strategy receives. The
simulator behind it (``SimulatedBody``) also knows the lights and the arm's
geometry. The naive code is handed ``SensingOnly(body)``, which exposes
``sense`` and the two vector sizes; Python cannot truly hide the simulator
behind it, so the tests also run the naive strategy against a body written
as a bare closure with nothing else to reach.
"""
from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from . import arm, retina


@runtime_checkable
class SensingBody(Protocol):
    n_motors: int
    n_sensors: int

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        """Sensations ``(B, n_sensors)`` for motor states ``(B, n_motors)``,
        probed one after the other in a static environment; the arm rests at
        the last row afterwards."""


class SimulatedBody:
    """Arm + retina simulator in a given light configuration (ground truth side)."""

    n_motors = arm.N_JOINTS

    def __init__(self, receptor_positions: np.ndarray, lights_world: np.ndarray | None = None,
                 motor_state: np.ndarray | None = None):
        self.receptor_positions = np.asarray(receptor_positions, dtype=float)
        self.n_sensors = len(self.receptor_positions)
        self.lights_world = None if lights_world is None else np.asarray(lights_world, float)
        self.motor_state = None if motor_state is None else np.asarray(motor_state, float)
        self.queries = 0          # motor states probed so far
        self.calls = 0            # sense() calls (round trips in the ROS graph)

    def set_lights(self, lights_world: np.ndarray) -> None:
        self.lights_world = np.asarray(lights_world, dtype=float)

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        return self.sense_with_poses(motor_states)[0]

    def sense_with_poses(self, motor_states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``sense`` and the eye poses ``(B, 3)`` it computed on the way (ground
        truth, for the evaluator): the forward model runs once per row."""
        if self.lights_world is None:
            raise RuntimeError("SimulatedBody.sense called before any lights were set")
        motor_states = np.asarray(motor_states, dtype=float)
        if motor_states.ndim != 2 or motor_states.shape[1] != self.n_motors:
            raise ValueError(f"motor_states must have shape (B, {self.n_motors}), "
                             f"got {motor_states.shape}")
        self.queries += len(motor_states)
        self.calls += 1
        if len(motor_states):
            self.motor_state = motor_states[-1].copy()
        pose = arm.forward(motor_states)
        return retina.sensation(pose, self.lights_world, self.receptor_positions), pose

    def sensor_pose(self, motor_states: np.ndarray) -> np.ndarray:
        """Ground truth pose of the eye (evaluation only)."""
        return arm.forward(np.asarray(motor_states, dtype=float))


class SensingOnly:
    """Expose only ``sense`` and the vector sizes of a body: what a naive agent may touch."""

    __slots__ = ("_sense", "n_motors", "n_sensors")

    def __init__(self, body: SensingBody):
        self._sense = body.sense
        self.n_motors = int(body.n_motors)
        self.n_sensors = int(body.n_sensors)

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        return self._sense(motor_states)
