"""The naive agent's measure of a MuJoCo body through its pixels' rounding:
images repeat exactly and lie on 256 gray levels, which it finds itself
(the lattice of the values, no parameter names it), and the pose rank and
POV dimension of both models from Jacobians fitted over clouds of states.
Skipped, saying what to install, where MuJoCo cannot render."""
from __future__ import annotations

import numpy as np
import pytest

from sensorispace_ros.bodies.mujoco_render import rendering_problem
from sensorispace_ros.core.body import SensingOnly
from sensorispace_ros.core.naive.noise import measure_body
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.sense_memory import CountingBody, MotorPhase

from test_mujoco_body import ARM, OTHER, world_of

PROBLEM = rendering_problem()
pytestmark = pytest.mark.skipif(PROBLEM is not None, reason=f"MuJoCo cannot render: {PROBLEM}")

# Small clouds and few probes: the structure, not its margin, at test cost.
SMALL = NaiveParams(cloud_pairs=64, cloud_max_pairs=256, structure_probes=4)


@pytest.mark.parametrize("which,rank,pov_dim", [("arm", 3, 1), ("other", 3, 0)])
def test_the_naive_agent_measures_a_mujoco_body_through_its_rounding(which, rank, pov_dim):
    world = world_of(ARM) if which == "arm" else world_of(None, **OTHER)
    simulator = world.body(lights=world.initial_lights)
    body = CountingBody(SensingOnly(simulator))
    phase = MotorPhase(simulator.description.periods)
    structure, params = measure_body(body, phase.to_phase(np.asarray(world.m0, float)), SMALL)
    assert (structure.pose_rank, structure.pov_dim) == (rank, pov_dim)
    # Gray levels: the rounding's sd is a twelfth of a level's square, not
    # what second differences of a staircase see.
    assert structure.noise == pytest.approx(1.0 / np.sqrt(12.0))
    assert params.match_tol * structure.gain < 0.5 * _smallest_displacement_change(world)


def _smallest_displacement_change(world) -> float:
    """The least the world's first six changes (moves of the object, or a
    rearrangement) change the image seen from the start (L2 over receptors)."""
    simulator = world.body(lights=world.initial_lights)
    rest = simulator.sense(np.asarray(world.m0, float)[None]).astype(float)[0]
    changes = []
    for event in world.events[:6]:
        simulator.set_lights(event.lights)
        changes.append(np.linalg.norm(
            simulator.sense(np.asarray(world.m0, float)[None]).astype(float)[0] - rest))
    return float(min(c for c in changes if c > 0))
