"""How far a noisy naive run's POVs lie from the start's lattice of positions.

Every compensation moves the eye by a whole number of grid steps from the
pose its anchor was recorded at, so the true positions of a run's POVs lie
on one lattice, the start's, as long as every rest of the arm does; a rest
off it puts every POV found after it on a lattice of its own. Runs the
naive agent (lockstep) on a body with imperfections no parameter names
(``ImperfectSensing``, as ``bench/noisy_naive.py``) for the first
``--events`` changes and prints one JSON line: POVs, wrong compensations
(pose more than a quarter grid step from the asked one), distinct
positions (POVs a quarter grid step apart), motor states, and
the POVs' offsets from the start's lattice (grid steps: median, 90th
percentile, share within 0.05 and 0.125); then every change of the rest's
offset by more than 0.03 step, with the orientation of the new rest::

    .venv/bin/python bench/noisy_lattice.py --config config/paper.yaml --seed 0 \\
        --noise 1e-4 --events 600

Diagnostics only: nothing here is the agent's.
"""
from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import sys
import time
from pathlib import Path

import numpy as np

from sensorispace_ros import config as config_mod
from sensorispace_ros.core.naive import run as naive_run
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.run_world import run_world

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "core"))
from imperfect_bodies import ImperfectSensing  # noqa: E402  (a test helper, shared)


class RestLog(naive_run.NaiveAgent):
    """``NaiveAgent`` that keeps its rest (body units) after every reaction."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.rests: list = []

    def react(self, passive_sensation):
        reaction = super().react(passive_sensation)
        self.rests.append((reaction.event, reaction.rest_motor_state, self._rest_pov))
        return reaction


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", default="config/paper.yaml")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--events", type=int, default=600)
    for name in ("noise", "laplace", "relative", "quantum", "motor_noise", "dropout"):
        parser.add_argument(f"--{name}", type=float, default=0.0)
    args = vars(parser.parse_args())
    cfg = config_mod.load_config(args.pop("config"))
    seed, events = args.pop("seed"), args.pop("events")
    world = run_world(cfg, seed)
    world = dataclasses.replace(world, events=world.events[:events])
    wrapper = functools.partial(ImperfectSensing, seed=seed + 7919,
                                **{k: v for k, v in args.items() if v})
    original = naive_run.NaiveAgent
    naive_run.NaiveAgent = RestLog
    started = time.perf_counter()
    try:
        explored = naive_run.explore_naive(world, NaiveParams(**cfg["naive"]),
                                           body_wrapper=wrapper)
    finally:
        naive_run.NaiveAgent = original
    agent, arm, step = explored.agent, world.arm, world.spacing
    centers = np.asarray(explored.centers)
    pose0 = arm.forward(np.asarray(world.m0, float)[None])[0]
    origin = pose0[:2] - centers[0] + centers[min(1, len(centers) - 1)]

    def offset(poses):
        steps = (np.asarray(poses)[..., :2] - origin) / step
        return steps - np.round(steps)

    wrong = 0
    for rec in agent.compensations:
        target = arm.forward(rec.anchor_motor_state[None])[0]
        target[:2] += centers[rec.event] - centers[rec.anchor_event]
        pose = arm.forward(rec.motor_state[None])[0]
        wrong += bool(arm.pose_error(pose[None], target[None])[0] > step / 4)
    positions = arm.forward(agent.points_of_view[:, 0])
    distance = np.linalg.norm(offset(positions), axis=1)
    from scipy.spatial import cKDTree
    close = cKDTree(positions[:, :2]).query_pairs(step / 4, output_type="ndarray")
    distinct = len(positions) - len(np.unique(close.max(axis=1))) if len(close) else len(positions)
    print(json.dumps({
        "events": events, "povs": agent._store.count, "distinct_positions": int(distinct),
        "wrong": wrong,
        "compensations": len(agent.compensations), "queries": agent.queries_total,
        "offset_median": round(float(np.median(distance)), 4),
        "offset_p90": round(float(np.percentile(distance, 90)), 4),
        "within_0.05": round(float(np.mean(distance < 0.05)), 3),
        "within_0.125": round(float(np.mean(distance < 0.125)), 3),
        "wall_s": round(time.perf_counter() - started, 1)}))
    before = np.zeros(2)
    for event, motor, pov in agent.rests:
        pose = arm.forward(np.asarray(motor)[None])[0]
        here = offset(pose)
        if np.linalg.norm(here - before) > 0.03:
            print(json.dumps({"rest moved at": event, "pov": int(pov),
                              "offset": np.round(here, 3).tolist(),
                              "orientation": round(float(pose[2] - pose0[2]), 3)}))
        before = here


if __name__ == "__main__":
    main()
