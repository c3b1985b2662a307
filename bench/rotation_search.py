"""Which compensable (position, orientation) visits of a turning world the naive
agent reaches, by orientation and by the eye's distance from the arm's base.

Every pose is visited once, so a missed compensation is missed for good: the
agent's coverage is the share of compensable visits its one search finds.
Steps the agent through the first ``--changes`` changes of the world (ground
truth joined here, never shown to the agent) and prints one JSON line::

    .venv/bin/python bench/rotation_search.py --config config/rotations.yaml \\
        --seed 0 --changes 600 --set naive.probe_grid=6 --set naive.probe_starts=8
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np

from sensorispace_ros import config
from sensorispace_ros.core.body import SensingOnly
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.run import _passive_sensation
from sensorispace_ros.core.paper.exploration import in_working_region, moved_pose
from sensorispace_ros.core.run_world import run_world


def reached_visits(cfg: dict, seed: int, changes: int) -> dict:
    """The compensable visits among the first ``changes`` and which the agent reached."""
    world = run_world(cfg, seed)
    body = world.body(lights=world.initial_lights)
    agent = NaiveAgent(SensingOnly(body), NaiveParams(**cfg["naive"]))
    agent.start(world.m0, seed=world.seed)
    pose0 = world.arm.forward(world.m0)
    rows = []
    started = time.perf_counter()
    for event in world.events[:changes]:
        body.set_lights(event.lights)
        reaction = agent.react(_passive_sensation(body))
        target = moved_pose(pose0, world.initial_center, event.center, float(event.orientation))
        if not in_working_region(world.arm, target):
            continue
        poses = world.arm.forward(agent.points_of_view[reaction.new_pov_ids, 0])
        hit = np.any((np.linalg.norm(poses[:, :2] - target[:2], axis=1) < 1e-5)
                     & (np.abs(np.angle(np.exp(1j * (poses[:, 2] - target[2])))) < 1e-5))
        rows.append((event.orientation_index, float(np.hypot(*target[:2])), bool(hit)))
    orientation = np.array([r[0] for r in rows], dtype=int)
    radius = np.array([r[1] for r in rows])
    hit = np.array([r[2] for r in rows], dtype=bool)
    bands = [(1.0, 1.5), (1.5, 2.0), (2.0, 2.5), (2.5, 3.0 + 1e-9)]
    return {
        "changes": changes, "compensable": len(rows), "reached": int(hit.sum()),
        "by_orientation": {int(o): [int(hit[orientation == o].sum()),
                                    int(np.sum(orientation == o))]
                           for o in np.unique(orientation)},
        "by_radius": {f"{lo}-{min(hi, 3.0)}": [int(hit[(radius >= lo) & (radius < hi)].sum()),
                                              int(np.sum((radius >= lo) & (radius < hi)))]
                      for lo, hi in bands},
        "seconds": round(time.perf_counter() - started, 1),
        "seconds_by_stage": {k: round(v, 1) for k, v in agent.seconds_by_stage.items()},
    }




def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", required=True)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--changes", type=int, default=600)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="a parameter override, e.g. naive.probe_grid=6 (YAML value)")
    args = parser.parse_args(argv)
    overrides = config.parse_overrides(args.set)
    cfg = config.load_config(args.config, overrides)
    print(json.dumps({"config": args.config, "seed": args.seed, "set": overrides,
                      **reached_visits(cfg, args.seed, args.changes)}))


if __name__ == "__main__":
    main()
