"""The naive agent and its representation on a body you write yourself.

The body is a plain Python function, ``sense(motor_states) -> sensations``:
here a planar arm of three unit links and an eye at its tip, whose receptors
see a few point lights on an object. The agent gets that function and the
number of joints, nothing else. The object moves over a small grid; after
each move the agent tries to bring its sensation back (to compensate), and
the points of view it collects become its representation of space. Offline,
no ROS; it runs in seconds.

    .venv/bin/python examples/naive_agent_on_your_body.py
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros import config
from sensorispace_ros.core.body_description import BodyDescription
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.offline.representation import build_representation

RNG = np.random.default_rng(0)
LIGHTS = RNG.uniform(-1.5, 1.5, size=(6, 2)) + [4.0, 0.0]   # the object's lights, at rest
RECEPTORS = np.linspace(-0.5, 0.5, 6)                         # across the eye's retina
M0 = np.array([0.1, -1.5, 2.2, -0.8])                         # joints 1-3 and the eye, rad


def eye_pose(motor: np.ndarray) -> np.ndarray:
    """Where the eye is (x, y) and where it looks (alpha): ground truth, the agent never sees it."""
    angles = np.cumsum(motor, axis=-1)
    x = np.cos(angles[..., :3]).sum(axis=-1)
    y = np.sin(angles[..., :3]).sum(axis=-1)
    return np.stack([x, y, angles[..., 3]], axis=-1)


class ObjectWorld:
    """The lights, moved by the object, and the arm, resting where the last
    command left it; ``sense`` is all the agent may call."""

    def __init__(self):
        self.offset = np.zeros(2)
        self.rest = M0.copy()

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        motor_states = np.asarray(motor_states, dtype=float)
        self.rest = motor_states[-1].copy()
        return self.seen(motor_states)

    def seen(self, motor_states: np.ndarray) -> np.ndarray:
        """What the eye sees from ``motor_states`` (B, 4): (B, receptors)."""
        pose = eye_pose(motor_states)
        rel = (LIGHTS + self.offset)[None] - pose[:, None, :2]          # (B, L, 2)
        c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
        ahead = rel[..., 0] * c[:, None] + rel[..., 1] * s[:, None]    # along the gaze
        side = -rel[..., 0] * s[:, None] + rel[..., 1] * c[:, None]
        image = side / np.maximum(ahead, 1e-3)                           # pinhole projection
        seen = np.exp(-((image[:, None, :] - RECEPTORS[None, :, None]) / 0.3) ** 2)
        light = np.exp(-0.1 * np.hypot(ahead, side)) * (ahead > 0.1)
        return (seen * light[:, None, :]).sum(axis=-1)                   # (B, receptors)


class Body:
    """What the agent receives: ``sense`` and the sizes of its vectors."""

    def __init__(self, world: ObjectWorld):
        self.sense = world.sense
        self.n_motors, self.n_sensors = len(M0), len(RECEPTORS)
        self.description = BodyDescription.revolute(self.n_motors, self.n_sensors)


def main(grid_count: int = 4, half_width: float = 0.6) -> float:
    world = ObjectWorld()
    agent = NaiveAgent(Body(world), NaiveParams())
    agent.start(M0)
    ticks = np.linspace(-half_width, half_width, grid_count)
    moves = [np.array([x, y]) for x in ticks for y in ticks]
    for offset in RNG.permutation(moves):
        world.offset = offset
        agent.react(world.seen(world.rest[None])[0])   # what the resting eye sees now
    povs = agent.points_of_view
    pairs, set_ids = agent.equality_sets()

    # Coverage (ground truth, the agent never sees it): of the eye positions
    # that compensate the object's positions (the start's moved by the
    # object's offset), the fraction a point of view of the agent's holds.
    positions = eye_pose(povs[:, 0])[:, :2] if len(povs) else np.zeros((0, 2))
    targets = eye_pose(M0)[:2] + np.array([np.zeros(2), *moves])
    gaps = np.linalg.norm(targets[:, None] - positions[None], axis=-1)
    covered = int(np.sum(gaps.min(axis=1, initial=np.inf) < 1e-3))
    coverage = covered / len(targets)
    print(f"{len(povs)} points of view, {len(pairs)} equality pairs; "
          f"coverage {coverage:.2f} ({covered} of {len(targets)} positions)")

    if len(povs) >= 4:
        cfg = config.load_config(overrides={"representation.cca.n_epochs": 20,
                                            "representation.regularization.iterations": 2})
        representation = build_representation(povs, pairs, set_ids, cfg, seed=0, processes=1)
        print(f"representation: {sorted(representation.before)} embeddings of "
              f"{len(representation.distance)} points of view")
    return coverage


if __name__ == "__main__":
    main()
