"""A MuJoCo model as a body: its description, its pixels, its object, its
ground truth, and the errors a model that lacks a named part gives. Needs
the mujoco package and EGL; without them every test here is skipped, saying
what to install (bodies.mujoco_render.rendering_problem)."""
from __future__ import annotations

import numpy as np
import pytest

from shared import REPO
from sensorispace_ros import config
from sensorispace_ros.bodies.mujoco_render import rendering_problem

PROBLEM = rendering_problem()
pytestmark = pytest.mark.skipif(PROBLEM is not None, reason=f"MuJoCo cannot render: {PROBLEM}")

ARM = REPO / "config" / "mujoco-smoke.yaml"
OTHER = {"body.kind": "mujoco", "mujoco.model": "tests/bodies/other_arm.xml",
         "mujoco.camera": "lens", "mujoco.joints": ["shoulder", "elbow", "wrist"],
         "mujoco.object": "target", "mujoco.image": [12, 10], "mujoco.channels": "rgb",
         "arm.initial_motor_state": [0.3, 1.0, 0.9], "world.grid_count": 6,
         "world.grid_half_width": 1.0}


def world_of(path=None, **overrides):
    from sensorispace_ros.bodies import run_world
    return run_world(config.load_config(path, overrides))


@pytest.fixture(scope="module")
def arm_world():
    return world_of(ARM)


@pytest.fixture(scope="module")
def other_world():
    return world_of(None, **OTHER)


def compensating_state(world, event):
    """The paper's compensation of ``event`` from the start (forward model),
    None where it fails."""
    from sensorispace_ros.core.paper.compensation import compensate_pose
    target = world.arm.forward(world.m0) + np.r_[event.center - world.initial_center, 0.0]
    state, _, ok = compensate_pose(world.m0, target, threshold=1e-4, body_arm=world.arm)
    return state if ok else None


def test_description_comes_from_the_model(arm_world, other_world):
    description = arm_world.body().description
    assert description.joint_names == ("joint1", "joint2", "joint3", "joint4")
    assert description.unit == "rad" and description.periods == (2 * np.pi,) * 4
    assert description.receptors == 16 * 16
    other = other_world.body().description
    assert other.joint_names == ("shoulder", "elbow", "wrist")
    assert other.receptors == 12 * 10 * 3


def test_default_joints_are_the_hinges_outside_the_object():
    from sensorispace_ros.bodies.mujoco_model import MujocoSpec
    cfg = config.load_config(None, {**OTHER, "mujoco.joints": []})
    assert MujocoSpec.load(cfg).joint_names == ("shoulder", "elbow", "wrist", "flap")
    # The flag's hinge turns about x: no planar chain the ground truth can describe.
    with pytest.raises(config.ConfigError, match="hinges about \\+z; joints shoulder, elbow, "
                                                 "wrist, flap have axes"):
        world_of(None, **{**OTHER, "mujoco.joints": [],
                          "arm.initial_motor_state": [0.3, 1.0, 0.9, 0.0]})


def test_pixels_are_uint8_and_see_the_object(arm_world):
    body = arm_world.body(lights=arm_world.initial_lights)
    images = body.sense(np.vstack([arm_world.m0, arm_world.m0 + 0.05]))
    assert images.dtype == np.uint8 and images.shape == (2, 256)
    assert images[0].max() > 100 and images[0].min() < 10       # spheres on black
    assert not np.array_equal(images[0], images[1])                # the camera moved
    assert body.queries == 2 and body.calls == 1
    np.testing.assert_array_equal(body.motor_state, arm_world.m0 + 0.05)


@pytest.mark.parametrize("name", ["arm_world", "other_world"])
def test_a_compensated_displacement_is_seen_alike(name, request):
    """The camera moved by the object's displacement sees what it saw: the
    paper's premise, on rendered pixels, for both models."""
    world = request.getfixturevalue(name)
    body = world.body(lights=world.initial_lights)
    before, _ = body.sense_at_rest()
    moved = next(e for e in world.events if e.kind == "translation"
                 and np.hypot(*(e.center - world.initial_center)) > 0.3
                 and compensating_state(world, e) is not None)
    body.set_lights(moved.lights)
    assert not np.array_equal(body.sense_at_rest()[0], before)
    after = body.sense(compensating_state(world, moved)[None])[0]
    assert np.abs(after.astype(int) - before.astype(int)).max() <= 1


def test_a_compensated_turn_is_seen_alike():
    """With ``world.rotation_count`` the object turns about its centre, its
    grains' headings with it: the camera moved and turned with the object
    (``moved_pose``) sees what it saw, and the same placement unturned does not."""
    from sensorispace_ros.bodies.mujoco_body import object_turn
    from sensorispace_ros.core.paper.compensation import compensate_pose
    from sensorispace_ros.core.paper.exploration import moved_pose

    world = world_of(ARM, **{"world.rotation_count": 4})
    body = world.body(lights=world.initial_lights)
    before, _ = body.sense_at_rest()
    start = world.arm.forward(world.m0)
    for event in (e for e in world.events if e.kind == "translation" and e.orientation != 0
                  and np.array_equal(e.offsets, world.initial_offsets)):
        target = moved_pose(start, world.initial_center, event.center, event.orientation)
        state, _, ok = compensate_pose(world.m0, target, threshold=1e-4, body_arm=world.arm)
        if ok:
            break
    assert ok and abs(object_turn(event.lights, world.layouts) - event.orientation) < 1e-9
    body.set_lights(event.lights)
    after = body.sense(state[None])[0]
    assert np.abs(after.astype(int) - before.astype(int)).max() <= 1
    # The geoms where the turned object puts them, but their headings unturned: not alike.
    body.layouts = []
    body.set_lights(event.lights)
    unturned = body.sense(state[None])[0]
    assert np.abs(unturned.astype(int) - before.astype(int)).max() > 20


def test_a_rearrangement_cannot_be_compensated(arm_world):
    world = arm_world
    event = next(e for e in world.events if e.kind == "redistribution"
                 and compensating_state(world, e) is not None)
    body = world.body(lights=world.initial_lights)
    before, _ = body.sense_at_rest()
    body.set_lights(event.lights)
    after = body.sense(compensating_state(world, event)[None])[0]
    assert np.abs(after.astype(int) - before.astype(int)).max() > 50


@pytest.mark.parametrize("name", ["arm_world", "other_world"])
def test_ground_truth_poses_are_mujocos(name, request):
    world = request.getfixturevalue(name)
    body = world.body(lights=world.initial_lights)
    states = world.m0 + np.random.default_rng(0).uniform(-2, 2, (20, world.arm.n_joints))
    _, poses = body.sense_with_poses(states)
    expected = world.arm.forward(states)
    np.testing.assert_allclose(poses[:, :2], expected[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (poses[:, 2] - expected[:, 2]))), 0,
                               atol=1e-9)


def test_the_other_models_chain(other_world):
    assert other_world.arm.eye == "link"
    np.testing.assert_allclose(other_world.arm.segments, (1.3, 0.9, 0.6))
    assert other_world.arm.pose_rank == 3 and other_world.arm.pov_dim == 0


def test_the_other_model_runs_the_paper_strategy_by_configuration_alone():
    from sensorispace_ros.offline.strategies import run_strategy
    out = run_strategy(config.load_config(None, OTHER), "paper", 0)
    metrics = out.metrics
    assert metrics["exploration.compensated"] >= 10
    assert metrics["pov.count"] == metrics["exploration.compensated"] + 1
    assert metrics["pov.max_pose_drift"] < 1e-9
    assert out.povs.shape[2] == 3                   # three joints


def test_physics_settles_near_the_command(arm_world):
    world = world_of(ARM, **{"mujoco.settle": "physics"})
    body = world.body(lights=world.initial_lights)
    command = world.m0 + np.array([0.2, -0.1, 0.1, 0.3])
    _, poses = body.sense_with_poses(command[None])
    reached = body.last_reached[0]
    assert 0 < np.abs(reached - command).max() < 1e-3       # near, not exact
    np.testing.assert_allclose(poses[0], world.arm.forward(reached), atol=1e-9)


@pytest.mark.parametrize("override, message", [
    ({"mujoco.camera": "nose"}, "mujoco.camera: the model has no camera 'nose' (its cameras: eye)"),
    ({"mujoco.joints": ["joint1", "knee"]},
     "mujoco.joints: the model has no hinge joint 'knee' outside the object (its hinges: "
     "joint1, joint2, joint3, joint4)"),
    ({"mujoco.object": "base"}, "mujoco.object: the model has no mocap body 'base' (its mocap "
                                "bodies: object)"),
    ({"arm.initial_motor_state": [0.0, 0.0]}, "arm.initial_motor_state: must hold one value "
                                              "per joint of arm_camera.xml"),
    ({"mujoco.model": "models/none.xml"}, "mujoco.model: no such file"),
])
def test_a_missing_part_is_named_with_what_the_model_has(override, message):
    with pytest.raises(config.ConfigError) as error:
        world_of(ARM, **override)
    assert message in str(error.value)


def test_the_simulated_body_stays_the_default():
    from sensorispace_ros.bodies import run_world
    from sensorispace_ros.core.run_world import run_world as simulated
    cfg = config.load_config(REPO / "config" / "smoke.yaml")
    assert cfg["body"]["kind"] == "simulated"
    ours, theirs = run_world(cfg), simulated(cfg)
    assert type(ours) is type(theirs)
    np.testing.assert_array_equal(ours.initial_lights, theirs.initial_lights)
    assert [e.grid_index for e in ours.events] == [e.grid_index for e in theirs.events]


def test_a_graph_runs_truth_is_the_models_chain(other_world):
    """The evaluator of a graph run (POVs only) poses them by the model's chain,
    not by the simulated arm of ``arm.*``."""
    from sensorispace_ros.evaluation.ground_truth import ground_truth_from_motor
    states = other_world.m0 + np.random.default_rng(1).uniform(-1, 1, (5, 1, 3))
    truth = ground_truth_from_motor(states, config.load_config(None, OTHER))
    np.testing.assert_allclose(truth["true_poses"], other_world.arm.forward(states[:, 0]))


def test_a_graph_runs_grid_is_the_worlds(arm_world):
    """The object grid written for a graph run is the one its world moves the
    object over (laid about the object's start), as the offline run writes it."""
    from sensorispace_ros.core.world import position_grid
    from sensorispace_ros.evaluation.ground_truth import ground_truth_from_motor
    cfg = config.load_config(ARM)
    laid = position_grid(cfg["world"]["grid_half_width"], cfg["world"]["grid_count"])
    assert not np.allclose(arm_world.grid, laid)       # the start's grid is not the centred one
    truth = ground_truth_from_motor(arm_world.m0[None, None], cfg)
    np.testing.assert_array_equal(truth["grid"], arm_world.grid)


def test_two_bodies_of_one_world_keep_their_own_object(arm_world):
    first = arm_world.body(lights=arm_world.initial_lights)
    seen, _ = first.sense_at_rest()
    rearranged = next(e for e in arm_world.events if e.kind == "redistribution")
    second = arm_world.body(lights=rearranged.lights)
    assert not np.array_equal(second.sense_at_rest()[0], seen)
    np.testing.assert_array_equal(first.sense_at_rest()[0], seen)


def test_a_state_looks_the_same_wherever_it_lies_in_a_batch(arm_world):
    """A motor state's frame does not depend on the frames drawn around it or
    on its batch: drawn in the same place of the framebuffer it is the same,
    bit for bit; elsewhere the rasterizer's subpixel rounding (the tile's
    offset) may move an edge sample, which changes a pixel by one gray level
    at most, at a few pixels (a batch over one read-back of 8 x 8 tiles)."""
    body = arm_world.body(lights=arm_world.initial_lights)
    states = arm_world.m0 + np.random.default_rng(2).uniform(-0.2, 0.2, (70, 4))
    batch = body.sense(states)
    np.testing.assert_array_equal(body.sense(states[:3])[:3], batch[:3])
    again = states.copy()
    again[5:] = states[5:][::-1]                  # same tiles for rows 0-4, others shuffled
    np.testing.assert_array_equal(body.sense(again)[:5], batch[:5])
    moved = body.sense(states[::-1])[::-1].astype(int) - batch
    assert np.abs(moved).max() <= 1
    assert np.count_nonzero(moved) <= 1e-3 * moved.size
    assert len(np.unique(batch, axis=0)) == 70            # distinct states, distinct frames


def test_the_other_model_has_a_configuration_of_its_own():
    """config/mujoco-other.yaml runs tests/bodies/other_arm.xml by configuration
    alone: its names, its links, its camera, its pixels."""
    world = world_of(REPO / "config" / "mujoco-other.yaml")
    np.testing.assert_allclose(world.arm.segments, (1.3, 0.9, 0.6))
    body = world.body(lights=world.initial_lights)
    assert body.description.joint_names == ("shoulder", "elbow", "wrist")
    assert body.description.receptors == 12 * 10 * 3
    assert body.sense_at_rest()[0].max() > 50                  # it sees its object


@pytest.mark.parametrize("where", ["grid", "center"])
def test_the_object_starts_on_its_grid_unless_told_the_centre(arm_world, where):
    """With an even grid count, ``grid`` starts the object on a grid position (every change a
    whole number of steps from it) that it is not moved to again; ``center`` keeps it half a
    step off every grid position."""
    world = arm_world if where == "grid" else world_of(ARM, **{"world.initial_position": where})
    assert len(world.grid) % 2 == 0 and int(np.sqrt(len(world.grid))) % 2 == 0
    steps = (world.grid - world.initial_center) / world.spacing
    visited = {e.grid_index for e in world.events}
    if where == "grid":
        assert np.allclose(steps, np.round(steps), atol=1e-9)
        start = int(np.argmin(np.hypot(*(world.grid - world.initial_center).T)))
        assert np.allclose(world.grid[start], world.initial_center)
        assert start not in visited and len(visited) == len(world.grid) - 1
    else:
        assert np.allclose(np.abs(steps - np.floor(steps)), 0.5, atol=1e-9)
        assert len(visited) == len(world.grid)
