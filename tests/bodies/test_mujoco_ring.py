"""config/mujoco-ring.yaml lays the object's grid round the hole of the
arm's points of view: the camera positions whose point of view is whole
(reachable, not split) form a ring the Betti rule reads as one (β0 = β1 =
1), where config/mujoco-arm.yaml's grid leaves it open (β1 = 0), and the
ring's band is at least two grid steps wide on every side of the hole.
Geometry only (no rendering), from the model's own chain; skipped where
MuJoCo cannot load a model."""
from __future__ import annotations

import numpy as np
import pytest

from shared import REPO
from sensorispace_ros import config
from sensorispace_ros.bodies.mujoco_render import rendering_problem

PROBLEM = rendering_problem()
pytestmark = pytest.mark.skipif(PROBLEM is not None, reason=f"MuJoCo cannot render: {PROBLEM}")


def whole_positions(path):
    """The camera positions of the grid whose point of view is whole, and the grid step."""
    from sensorispace_ros.bodies import run_world
    from sensorispace_ros.core.paper.exploration import in_working_region

    world = run_world(config.load_config(path))
    pose0 = world.arm.forward(world.m0)
    targets = pose0 + np.column_stack([world.grid - world.initial_center,
                                       np.zeros(len(world.grid))])
    keep = np.array([in_working_region(world.arm, target) for target in targets])
    return targets[keep, :2], targets[~keep, :2], world.spacing


@pytest.mark.parametrize("name, betti1", [("mujoco-ring.yaml", 1), ("mujoco-arm.yaml", 0)])
def test_the_ring_config_encloses_the_hole(name, betti1):
    from sensorispace_ros.core.topology import betti_numbers, euclidean_distances, persistence

    whole, _, _ = whole_positions(REPO / "config" / name)
    betti = betti_numbers(persistence(euclidean_distances(whole)))
    assert (betti.betti0, betti.betti1) == (1, betti1)


def test_the_ring_is_two_steps_wide_round_the_hole():
    whole, dropped, step = whole_positions(REPO / "config" / "mujoco-ring.yaml")
    split = dropped[np.hypot(dropped[:, 0], dropped[:, 1]) < 1.5]
    assert len(split) > 20                  # the hole is several grid steps across
    centre = split.mean(axis=0)
    for angle in np.linspace(0.0, 2 * np.pi, 16, endpoint=False):
        ray = np.array([np.cos(angle), np.sin(angle)])
        # Whole positions within half a step of the ray, beyond the hole.
        offset = whole - centre
        along = offset @ ray
        across = np.abs(offset @ np.array([-ray[1], ray[0]]))
        beyond = along[(across < 0.5 * step) & (along > 0)]
        assert len(beyond) >= 2, f"fewer than two whole positions along {angle:.2f} rad"
