"""Reaching in (position, orientation) space: straightness on plane x circle."""
from __future__ import annotations

import numpy as np
import pytest

from sensorispace_ros.core.pose_reach import (angle_turns, goes_long_way, pose_distance,
                                              pose_path_straightness, pose_reaching_evaluation,
                                              wrap)


def _line(start, end_offset, n=7):
    """Poses on the straight line from ``start`` by ``end_offset`` (theta unwrapped
    along the way, stored wrapped)."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    poses = np.asarray(start, float) + t * np.asarray(end_offset, float)
    poses[:, 2] = wrap(poses[:, 2])
    return poses


def test_a_straight_path_across_the_cut_of_the_circle_scores_one():
    # theta from 2.8 rad through pi to 2.8 + 0.6 (stored as about -2.88)
    poses = _line((0.0, 0.0, 2.8), (1.0, 0.5, 0.6))
    assert np.any(np.diff(poses[:, 2]) < -np.pi)         # the stored angles do jump
    path = list(range(len(poses)))
    assert pose_path_straightness(path, poses, 2.0) == pytest.approx(1.0, abs=1e-12)
    assert not goes_long_way(path, poses)


def test_a_path_the_long_way_round_scores_worse():
    short = _line((0.0, 0.0, 2.8), (1.0, 0.0, 0.6))
    long = _line((0.0, 0.0, 2.8), (1.0, 0.0, 0.6 - 2 * np.pi), n=40)
    assert np.allclose(short[-1], long[-1]) and np.allclose(short[0], long[0])
    path = list(range(len(long)))
    assert goes_long_way(path, long)
    straight = np.hypot(1.0, 2.0 * 0.6)
    expected = np.hypot(1.0, 2.0 * (2 * np.pi - 0.6)) / straight
    assert pose_path_straightness(path, long, 2.0) == pytest.approx(expected, rel=1e-9)
    assert expected > 3


def test_an_angle_counts_as_the_arc_it_moves_the_sensor_at_the_length_scale():
    # an L: 1 along x, then a turn of 0.5 rad; at length scale 2 the turn is an arc of 1
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.5]])
    assert pose_distance(poses[1], poses[2], 2.0) == pytest.approx(1.0)
    assert pose_path_straightness([0, 1, 2], poses, 2.0) == pytest.approx(np.sqrt(2.0))
    # degrees, or no weight, would read another number
    assert pose_path_straightness([0, 1, 2], poses, 1.0) == pytest.approx(1.5 / np.hypot(1, .5))
    with pytest.raises(ValueError, match="length_scale"):
        pose_distance(poses[0], poses[1], 0.0)


def test_a_path_between_two_povs_of_one_pose_is_refused():
    poses = np.array([[0.0, 0.0, np.pi], [1.0, 0.0, 0.0], [0.0, 0.0, -np.pi]])
    with pytest.raises(ValueError, match="same pose"):
        pose_path_straightness([0, 1, 2], poses, 2.0)


def _plane_times_circle(n_xy=5, n_theta=8, step=0.25, length_scale=2.0):
    """A lattice of poses whose angle step moves the sensor by one lattice step."""
    angle_step = 2 * np.pi / n_theta
    grid = np.array([(x, y, k * angle_step) for x in range(n_xy) for y in range(n_xy)
                     for k in range(n_theta)], dtype=float)
    grid[:, :2] *= step
    return grid, step, angle_step * length_scale


def test_a_metric_that_cuts_the_circle_sends_paths_the_long_way():
    poses, step, arc = _plane_times_circle()
    rho = 2.0
    true = pose_distance(poses[:, None], poses[None], rho)
    torn = poses.copy()
    torn[:, 2] = np.mod(torn[:, 2], 2 * np.pi) * rho     # theta as a line: cut at 0
    cut = np.linalg.norm(torn[:, None] - torn[None], axis=-1)
    radius = 1.5 * max(step, arc)
    good = pose_reaching_evaluation(true, poses, rho, n_pairs=300, random_state=1,
                                    radius=radius)
    bad = pose_reaching_evaluation(cut, poses, rho, n_pairs=300, random_state=1,
                                   radius=radius)
    assert good["pairs"] == bad["pairs"]
    assert good["reached"] == bad["reached"] == 300
    assert good["long_way"] == 0 and bad["long_way"] > 30
    s_good = np.array(good["straightness"], float)
    s_bad = np.array(bad["straightness"], float)
    assert np.all(s_good >= 1 - 1e-12) and np.median(s_good) < 1.2
    assert np.median(s_bad) > np.median(s_good) and np.all(s_bad >= s_good - 1e-9)


def test_pairs_the_graph_does_not_join_are_not_reached():
    poses = np.array([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0],
                      [5, 0, 1], [5.1, 0, 1]], dtype=float)
    distance = pose_distance(poses[:, None], poses[None], 2.0)
    result = pose_reaching_evaluation(distance, poses, 2.0, n_pairs=50, random_state=0,
                                      radius=0.5)
    same_side = sum((s < 3) == (t < 3) for s, t in result["pairs"])
    assert result["n_components"] == 2
    assert result["reached"] == same_side < 50
    assert sum(v is None for v in result["straightness"]) == 50 - same_side


def test_two_povs_at_one_pose_are_reached_but_not_scored():
    poses = np.array([[0, 0, 0], [0, 0, 2 * np.pi], [0.1, 0, 0]], dtype=float)
    distance = pose_distance(poses[:, None], poses[None], 2.0) + 0.01 * (1 - np.eye(3))
    result = pose_reaching_evaluation(distance, poses, 2.0, n_pairs=40, random_state=0,
                                      radius=1.0)
    one_pose = sum({s, t} == {0, 1} for s, t in result["pairs"])
    assert one_pose > 0 and result["same_pose"] == one_pose and result["reached"] == 40


def test_a_target_half_a_turn_away_is_the_short_way_either_way():
    for end in (np.pi - 1e-4, np.pi + 1e-4, -np.pi - 1e-4):
        poses = _line((0.0, 0.0, 0.0), (1.0, 0.0, end), n=4)
        assert not goes_long_way([0, 1, 2, 3], poses)
    poses = _line((0.0, 0.0, 0.0), (1.0, 0.0, np.pi + 0.2), n=4)
    assert goes_long_way([0, 1, 2, 3], poses)


def test_an_angle_coordinate_tells_the_short_way_round_in_either_direction():
    rng = np.random.default_rng(3)
    theta = rng.uniform(-np.pi, np.pi, 60)
    pairs = np.column_stack([np.arange(60), rng.permutation(60)])
    for coordinate in (theta + 1.0, -theta + 2.5):          # a direction is a convention
        read = angle_turns(coordinate, theta, pairs)
        assert read["short_way_share"] == 1.0 and read["turn_error_median"] < 1e-12
    # a coordinate that goes round twice per turn reads many turns the wrong way
    doubled = angle_turns(2 * theta, theta, pairs)
    assert doubled["short_way_share"] < 0.8 and doubled["turn_error_median"] > 0.3
    half_turn = angle_turns(np.array([0.0, np.pi]), np.array([0.0, np.pi]), [[0, 1]])
    assert half_turn["scored"] == 0
