"""The turning world (``world.rotation_count``): its schedule, the rigid-motion
fit, the pose that compensates a turn, the paper strategy on it, and Betti
numbers up to H2."""
import numpy as np
import pytest

from sensorispace_ros.core import retina, world
from sensorispace_ros.core.paper.exploration import (build_world, explore_paper, moved_pose,
                                                     rigid_motion_residual)
from sensorispace_ros.core.topology import euclidean_distances
from sensorispace_ros.core.looped_space import betti_up_to_h2
from sensorispace_ros.evaluation.rotations import compensable_poses

TURNING = {"grid_count": 10, "rotation_count": 6}


@pytest.fixture(scope="module")
def turning_world():
    return build_world(0, TURNING)


def test_orientations_are_evenly_spaced_over_a_full_turn():
    assert np.array_equal(world.orientations(0), [0.0])
    angles = world.orientations(8)
    assert np.allclose(np.diff(angles), np.pi / 4) and angles[0] == 0.0
    with pytest.raises(ValueError, match="rotation_count"):
        world.orientations(-1)


def test_without_rotations_every_event_keeps_the_lights_offsets():
    w = build_world(0, {"grid_count": 10})
    assert all(e.orientation == 0.0 and e.orientation_index == 0 for e in w.events)
    assert all(np.array_equal(e.lights, e.center + e.offsets) for e in w.events)


def test_every_position_and_orientation_is_visited_once(turning_world):
    visits = [(e.grid_index, e.orientation_index) for e in turning_world.events
              if e.kind == world.TRANSLATION]
    start = int(np.flatnonzero(np.all(turning_world.grid == turning_world.initial_center,
                                      axis=1))[0])
    # all but the start: the object's grid position and orientation before the first change
    assert sorted(visits) == [(g, k) for g in range(100) for k in range(6) if (g, k) != (start, 0)]


def test_tracking_order_turns_the_object_in_place_before_moving_on():
    w = build_world(0, {**TURNING, "order": "tracking", "redistribution_probability": 0.0})
    first = w.events[:6]
    assert {e.grid_index for e in first} == {first[0].grid_index}
    assert [e.orientation_index for e in first] == list(range(6))


def test_lights_turn_rigidly_about_the_centre(turning_world):
    for e in turning_world.events[:50]:
        distance = np.linalg.norm(e.lights - e.center, axis=1)
        assert np.allclose(distance, np.linalg.norm(e.offsets, axis=1))
        _, residual = rigid_motion_residual(turning_world.initial_lights, e.lights)
        assert residual < 1e-9 or e.kind == world.REDISTRIBUTION or \
            not np.allclose(e.offsets, turning_world.initial_offsets)


def test_rigid_motion_fit_accepts_a_turn_and_rejects_a_redistribution():
    rng = np.random.default_rng(1)
    lights = rng.normal(size=(10, 2))
    turned = np.array([3.0, -1.0]) + lights @ world.rotation_matrix(0.7).T
    assert rigid_motion_residual(lights, turned)[1] < 1e-12
    assert rigid_motion_residual(lights, rng.normal(size=(10, 2)))[1] > 0.1
    assert rigid_motion_residual(lights, lights[:, ::-1])[1] > 0.1   # a mirror is no motion


def test_the_moved_pose_senses_what_the_pose_sensed(turning_world):
    """The eye moved and turned with the object sees the same sensation."""
    w = turning_world
    pose0 = w.arm.forward(w.m0)
    before = retina.sensation(pose0, w.initial_lights, w.receptors)
    for e in w.events[:40]:
        if not np.allclose(e.offsets, w.initial_offsets):
            continue
        after = retina.sensation(moved_pose(pose0, w.initial_center, e.center, e.orientation),
                                 e.lights, w.receptors)
        assert np.allclose(np.asarray(after), np.asarray(before), atol=1e-12)


def test_paper_strategy_compensates_exactly_the_compensable_poses(turning_world):
    w = turning_world
    result = explore_paper(m0=w.m0, grid=w.grid, events=w.events,
                           initial_center=w.initial_center, body_arm=w.arm)
    events = {e.index: e for e in w.events}
    done = {(events[i].grid_index, events[i].orientation_index)
            for i in result.events_index[1:]}
    pairs, poses = compensable_poses(w)
    assert done == {tuple(p) for p in pairs}
    assert len(done) == result.compensated           # each pose once
    assert result.state_changes_compensated == 0
    assert len({k for _, k in done}) == 6            # every orientation is compensated
    # The eye turns with the object: its orientation is the start's plus the object's.
    pose0 = w.arm.forward(w.m0)
    turn = np.array([events[i].orientation for i in result.events_index[1:]])
    offset = np.angle(np.exp(1j * (result.true_poses[1:, 2] - pose0[2] - turn)))
    assert np.max(np.abs(offset)) < 1e-3


def _ring_times_circle(n_ring=14, n_turn=10, inner=2.0, outer=3.0):
    """Annulus x circle, sampled: (x, y, cos a, sin a); few points, as ripser's H2
    grows as the cube of them."""
    radius = np.linspace(inner, outer, 2)
    phi = np.linspace(0, 2 * np.pi, n_ring, endpoint=False)
    a = np.linspace(0, 2 * np.pi, n_turn, endpoint=False)
    r, p, t = np.meshgrid(radius, phi, a, indexing="ij")
    return np.column_stack([(r * np.cos(p)).ravel(), (r * np.sin(p)).ravel(),
                            2 * np.cos(t).ravel(), 2 * np.sin(t).ravel()])


@pytest.mark.slow
def test_betti_numbers_up_to_h2_read_a_circle_a_sphere_and_a_ring_times_circle():
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    circle = np.column_stack([np.cos(t), np.sin(t)])
    got = betti_up_to_h2(euclidean_distances(circle))
    assert (got["betti0"], got["betti1"], got["betti2"]) == (1, 1, 0)
    rng = np.random.default_rng(0)
    sphere = rng.normal(size=(300, 3))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    got = betti_up_to_h2(euclidean_distances(sphere), max_points=150, k=2.0)
    assert (got["betti0"], got["betti1"], got["betti2"]) == (1, 0, 1)
    ring_circle = _ring_times_circle()
    got = betti_up_to_h2(euclidean_distances(ring_circle), max_points=400, k=2.0)
    assert (got["betti0"], got["betti1"], got["betti2"]) == (1, 2, 1)


def test_equality_sets_by_orientation_pair_translations_within_an_orientation():
    from sensorispace_ros.core.paper.equality_sets import equality_sets_by_orientation

    w = build_world(0, {"grid_count": 12, "rotation_count": 4})
    result = explore_paper(m0=w.m0, grid=w.grid, events=w.events,
                           initial_center=w.initial_center, body_arm=w.arm)
    poses = result.true_poses
    pairs, set_ids = equality_sets_by_orientation(poses, w.spacing)
    assert len(pairs) > 100 and len(np.unique(set_ids)) > 10
    turn = np.angle(np.exp(1j * (poses[pairs[:, 1], 2] - poses[pairs[:, 0], 2])))
    assert np.max(np.abs(turn)) < 1e-6                      # no turn inside a set
    step = poses[pairs[:, 1], :2] - poses[pairs[:, 0], :2]
    for s in np.unique(set_ids):                            # one displacement per set
        assert np.ptp(step[set_ids == s], axis=0).max() < 1e-6
    orientation_of_set = {}
    for s, a in zip(set_ids, np.round(poses[pairs[:, 0], 2], 6)):
        orientation_of_set.setdefault(s, set()).add(a)
    assert max(len(v) for v in orientation_of_set.values()) > 1   # sets span orientations


def test_naive_compensation_targets_and_pose_coverage():
    from sensorispace_ros.evaluation.rotations import compensation_targets, pose_coverage

    anchor = np.array([[2.0, 0.0, 0.3]])
    target = compensation_targets(anchor, [[1.0, 0.0]], [[1.0, 1.0]], [np.pi / 2])
    assert np.allclose(target, [[1.0, 2.0, 0.3 + np.pi / 2]])
    reference = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, np.pi], [2.0, 1.0, 0.0]])
    found = np.array([[1.0, 1.0, 0.01], [1.0, 1.0, 0.02], [2.0, 1.0, np.pi]])
    numbers = pose_coverage(found, reference, tolerance=0.1)
    assert numbers["naive.distinct_positions"] == 2          # the first two are one pose
    assert numbers["naive.coverage_of_paper_positions"] == pytest.approx(1 / 3)
