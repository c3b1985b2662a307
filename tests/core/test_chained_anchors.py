"""The naive agent in a world whose object turns: anchors that relate to the
start only (``naive.chained_anchors``) and search starts from a fixed grid of
motor states (``naive.probe_grid``)."""
import numpy as np
import pytest

from sensorispace_ros.core.naive.anchors import Snapshot, anchor_requests
from sensorispace_ros.core.naive.equality_sets import RANK_FULL
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.run import explore_naive
from sensorispace_ros.core.paper.exploration import build_world, moved_pose
from sensorispace_ros.evaluation.rotations import compensable_poses


def _snapshot(event, chained):
    sensations = np.arange(6.0).reshape(1, 6) + event
    return Snapshot(event, sensations, np.array([RANK_FULL]), sensations[0] + 0.5,
                    np.zeros(4), 0, RANK_FULL, chained=chained)


@pytest.mark.parametrize("chained_anchors, searched", [(False, [0, 1]), (True, [1])])
def test_only_chained_anchors_are_searched_when_asked(chained_anchors, searched):
    pool = [_snapshot(2, chained=False), _snapshot(1, chained=True)]
    none = (np.zeros(0, dtype=int), np.zeros(0, dtype=int))
    params = NaiveParams(chained_anchors=chained_anchors, frontier_attempts=0,
                         unconfirmed_attempts=4, unconfirmed_max_povs=10)
    known, requests = anchor_requests(pool, [none, none], [-1, -1], np.array([RANK_FULL]),
                                      params, pov_samples=np.zeros((1, 2, 4)),
                                      frontier_budget=0)
    assert known == {} and [r.snapshot for r in requests] == searched


def _chain_run(params):
    """Events of a small turning world without redistribution, and for each
    compensated one whether the arm rests at the start's pose moved with the
    object (the start's chain)."""
    world = build_world(0, {"grid_count": 8, "rotation_count": 4,
                            "redistribution_probability": 0.0})
    explored = explore_naive(world, params)
    agent, pose0 = explored.agent, world.arm.forward(world.m0)
    compensable = {tuple(p) for p in compensable_poses(world)[0]}
    on_chain, reached = [], 0
    for record in agent.compensations:
        event = world.events[record.event - 1]
        target = moved_pose(pose0, world.initial_center, event.center, float(event.orientation))
        pose = world.arm.forward(record.motor_state)
        close = np.linalg.norm(pose[:2] - target[:2]) < 1e-5 and \
            abs(np.angle(np.exp(1j * (pose[2] - target[2])))) < 1e-5
        on_chain.append(close)
        reached += close and (event.grid_index, event.orientation_index) in compensable
    return np.asarray(on_chain), reached, len(compensable)


def test_chained_anchors_and_probe_starts_follow_the_start_through_turns():
    chained = NaiveParams(chained_anchors=True, probe_grid=6, frontier_attempts=0,
                          unconfirmed_max_povs=10 ** 6, unconfirmed_attempts=12,
                          snapshot_patience=10 ** 6)
    on_chain, reached, compensable = _chain_run(chained)
    assert on_chain.all()                   # every compensation relates to the start
    assert reached >= 0.8 * compensable
    default_on_chain, default_reached, _ = _chain_run(NaiveParams())
    assert default_reached < 0.5 * compensable and not default_on_chain.all()
