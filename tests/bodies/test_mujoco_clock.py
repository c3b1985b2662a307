"""A MuJoCo body on the row clock: the world changes under it and the clock
records how far each change moved the resting view, and a clock resumed at
its position (a restarted body node) answers as it did, physics included.
Needs the mujoco package and EGL; without them every test here is skipped,
saying what to install (bodies.mujoco_render.rendering_problem)."""
from __future__ import annotations

import numpy as np
import pytest

from shared import REPO
from sensorispace_ros import config
from sensorispace_ros.bodies.mujoco_render import rendering_problem

PROBLEM = rendering_problem()
pytestmark = pytest.mark.skipif(PROBLEM is not None, reason=f"MuJoCo cannot render: {PROBLEM}")

ARM = REPO / "config" / "mujoco-smoke.yaml"
CLOCK = {"world.clock": "rows", "world.change_interval": 7.0}


def world_and_cfg(**overrides):
    from sensorispace_ros.bodies import run_world
    cfg = config.load_config(ARM, {**CLOCK, **overrides})
    return run_world(cfg), cfg


def commands(world, count=6, rows=5):
    rng = np.random.default_rng(0)
    return [world.m0 + rng.normal(0.0, 0.2, (rows, world.m0.size)) for _ in range(count)]


@pytest.mark.parametrize("settle", ["kinematic", "physics"])
def test_changes_on_the_row_clock_are_measured_at_the_resting_view(settle):
    from sensorispace_ros.core.world_clock import clock_body
    world, cfg = world_and_cfg(**{"mujoco.settle": settle})
    clocked = clock_body(world.body(lights=world.initial_lights), world, cfg)
    for command in commands(world):
        clocked.sense(command)
    seen = clocked.rest_jumps[:clocked.state]
    assert clocked.state >= 2 and np.all(np.isfinite(seen))
    assert np.all(seen >= 0) and np.any(seen > 0)       # gray levels the object's move changed


def test_a_clock_resumed_at_its_position_settles_as_it_did():
    from sensorispace_ros.core.world_clock import clock_body
    world, cfg = world_and_cfg(**{"mujoco.settle": "physics"})
    fresh = lambda: clock_body(world.body(lights=world.initial_lights), world, cfg)  # noqa: E731
    first, again = fresh(), fresh()
    sent = commands(world)
    for command in sent[:3]:
        first.sense(command)
    at = first.position()
    assert len(at) == first.position_size > 3 + world.m0.size     # the physics rides along
    then = [(first.sense(c), first._body.last_reached.copy()) for c in sent[3:]]
    again.resume(at)
    for command, (images, reached) in zip(sent[3:], then):
        np.testing.assert_array_equal(again.sense(command), images)
        np.testing.assert_array_equal(again._body.last_reached, reached)
    assert (again.row, again.state) == (first.row, first.state)


def test_a_physics_state_set_again_settles_bit_for_bit():
    world, _ = world_and_cfg(**{"mujoco.settle": "physics"})
    body, other = world.body(lights=world.initial_lights), world.body(lights=world.initial_lights)
    body.sense((world.m0 + 0.5)[None])
    state = body.physics_state()
    target = (world.m0 + np.array([0.2, -0.1, 0.1, 0.3]))[None]
    body.sense(target)
    reached = body.last_reached.copy()
    other.sense(target)                          # from its own start: a settle of its own
    assert np.abs(other.last_reached - reached).max() > 0
    other.set_physics_state(state)
    other.sense(target)
    np.testing.assert_array_equal(other.last_reached, reached)
    with pytest.raises(ValueError, match=f"physics state: need {len(state)} values, got 3"):
        other.set_physics_state(state[:3])


def test_a_kinematic_body_has_no_physics_to_carry():
    world, _ = world_and_cfg(**{"mujoco.settle": "kinematic"})
    body = world.body(lights=world.initial_lights)
    assert body.physics_state().shape == (0,)
    body.set_physics_state(np.zeros(0))
