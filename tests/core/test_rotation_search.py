"""The naive agent's global search in the rotation world (``config/rotations.yaml``):
the compensable turned visits it must reach, one shot each (every (position,
orientation) pair is visited once). The configuration's search settings (a
4,096-state probe grid with 64 starts and 16 known POVs, the rank test at
1e-4, searches that crawl for up to 300 iterations) reach them; the smoke
profile's settings do not."""
from __future__ import annotations

import numpy as np
from shared import REPO

from sensorispace_ros import config
from sensorispace_ros.core.body import SensingOnly
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.run import _passive_sensation
from sensorispace_ros.core.paper.exploration import moved_pose
from sensorispace_ros.core.run_world import run_world
from sensorispace_ros.evaluation.rotations import compensable_poses

ROTATIONS = REPO / "config" / "rotations.yaml"
# The search settings of config/rotations-smoke.yaml (the smoke profile).
SMOKE_SEARCH = {"naive.probe_grid": 6, "naive.probe_starts": 8, "naive.rank_ratio": 1e-3,
                "naive.lm_stall_iterations": 3, "naive.lm_max_iterations": 40,
                "naive.lm_restarts": 2}


def _reached(overrides: dict, visits: int = 24) -> tuple[int, int]:
    """The first ``visits`` compensable visits of the rotation world (seed 0),
    in schedule order, handed to one agent: how many it compensates at the
    start's pose moved with the object, a POV of its own, and how many of
    those were at a turned orientation."""
    cfg = config.load_config(ROTATIONS, overrides)
    world = run_world(cfg, 0)
    compensable = {tuple(p) for p in compensable_poses(world)[0]}
    events = [e for e in world.events if (e.grid_index, e.orientation_index) in compensable]
    body = world.body(lights=world.initial_lights)
    agent = NaiveAgent(SensingOnly(body), NaiveParams(**cfg["naive"]))
    agent.start(world.m0, seed=world.seed)
    pose0 = world.arm.forward(world.m0)
    reached, turned = 0, 0
    for event in events[:visits]:
        body.set_lights(event.lights)
        reaction = agent.react(_passive_sensation(body))
        target = moved_pose(pose0, world.initial_center, event.center, float(event.orientation))
        poses = world.arm.forward(agent.points_of_view[reaction.new_pov_ids, 0])
        hit = np.any((np.linalg.norm(poses[:, :2] - target[:2], axis=1) < 1e-5)
                     & (np.abs(np.angle(np.exp(1j * (poses[:, 2] - target[2])))) < 1e-5))
        reached += bool(hit)
        turned += bool(hit) and event.orientation_index != 0
    return reached, turned


def test_the_rotation_profile_reaches_the_compensable_turned_visits():
    reached, turned = _reached({})
    assert reached >= 22 and turned >= 18           # of 24 visits, 20 of them turned


def test_the_smoke_search_settings_miss_most_of_them():
    reached, _ = _reached(SMOKE_SEARCH)
    assert reached <= 12
