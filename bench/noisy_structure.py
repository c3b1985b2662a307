"""The naive agent's structure stage alone (noise, pose rank, POV dimension,
start), on a configuration's body with the imperfections its ``world.retina.*``
and ``arm.motor_noise`` name: what ``NaiveAgent.start`` measures before its
first POV, in seconds instead of a whole run. One JSON line per seed::

    .venv/bin/python bench/noisy_structure.py --config config/paper.yaml --seeds 0-2 \\
        --set world.retina.noise=1e-3
    .venv/bin/python bench/noisy_structure.py --config config/bodies/*.yaml --seeds 0 \\
        --set world.retina.noise=1e-3

``motor states``: the rows the rank stage sensed (noise, probes, start).
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np

from sensorispace_ros import config as config_mod




def measure(config: str, seed: int, overrides: dict) -> dict:
    from sensorispace_ros.bodies import run_world
    from sensorispace_ros.core.body import SensingOnly
    from sensorispace_ros.core.naive.agent import NaiveAgent
    from sensorispace_ros.core.naive.params import NaiveParams

    cfg = config_mod.load_config(config, overrides={**overrides, "seed": seed})
    world = run_world(cfg, seed)
    agent = NaiveAgent(SensingOnly(world.body(lights=world.initial_lights)),
                       NaiveParams(**cfg["naive"]))
    started = time.perf_counter()
    agent._body.stage = "rank"
    agent._measure_body(agent._phase.to_phase(np.asarray(world.m0, float)), seed)
    s = agent.structure
    return {"config": config, "seed": seed, **overrides,
            "true_rank": int(world.arm.pose_rank), "pose_rank": s.pose_rank,
            "pov_dim": s.pov_dim, "votes": f"{s.votes}/{s.probes}",
            "weakest": float(f"{s.weakest:.3g}"), "floor": float(f"{s.floor:.3g}"),
            "rank_gap": float(f"{s.rank_gap:.3g}"), "noise": float(f"{s.noise:.3g}"),
            "receptor_noise": float(f"{s.receptor_noise:.3g}"),
            "fd_step": float(f"{s.fd_step:.3g}"), "motor_states": int(agent._body.total_rows),
            "moved": bool(agent.start_choice is not None and agent.start_choice.moved),
            "wall_s": round(time.perf_counter() - started, 1)}


def _seeds(text: str) -> list[int]:
    low, _, high = text.partition("-")
    return list(range(int(low), int(high or low) + 1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", nargs="+", default=["config/paper.yaml"])
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    overrides = config_mod.parse_overrides(args.set)
    for config in args.config:
        for seed in _seeds(args.seeds):
            print(json.dumps(measure(config, seed, overrides)), flush=True)


if __name__ == "__main__":
    main()
