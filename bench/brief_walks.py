"""The clocked agent's brief POV walk against the lockstep agent's full walk.

Both agents start alone in the static world of a lockstep naive run (its
configuration and seed), then walk again, each, every POV of that run from
its first motor state (the POVs whose start pins no pose in that world are
left out). Prints, as JSON: the POVs walked, rows a walk of each (median;
the brief walk's largest), the largest distance of a brief walk's sample
from its start's sensation (relative to the start's largest receptor
output), and the Hausdorff distance between the two walks' samples (median
and largest, phases on the torus) beside the median distance from a POV of
the run to its nearest::

    .venv/bin/sensorispace reproduce --strategy naive --config config/smoke.yaml --out /tmp/smoke
    .venv/bin/python bench/brief_walks.py /tmp/smoke [--knots 4] [--secant 2]
"""
from __future__ import annotations

import argparse
import json

import numpy as np

from sensorispace_ros.core.body import SensingOnly
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.clocked_agent import ClockedAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.run_world import run_world


def started(kind, world, params):
    agent = kind(SensingOnly(world.body(lights=world.initial_lights)), params)
    agent.start(world.m0, seed=world.seed)
    return agent


def walk(agent, state: np.ndarray):
    """Samples (phases) and rows of the POV of ``state`` (phases), or None."""
    before = agent._body.rows.get("pov", 0)
    agent._body.stage = "pov"
    with agent._body.fresh():
        indices, _ = agent._sample_povs(state[None])
    if not indices:
        return None, agent._body.rows.get("pov", 0) - before
    return agent._store.samples[indices[0]].copy(), agent._body.rows.get("pov", 0) - before


def _wrap(x: np.ndarray) -> np.ndarray:
    return (x + np.pi) % (2.0 * np.pi) - np.pi


def torus_hausdorff(a: np.ndarray, b: np.ndarray) -> float:
    """Hausdorff distance between two sample sets (phases) on the torus."""
    distance = np.linalg.norm(_wrap(a[:, None, :] - b[None, :, :]), axis=2)
    return float(max(distance.min(axis=0).max(), distance.min(axis=1).max()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", help="a lockstep naive run's directory (arrays.npz)")
    parser.add_argument("--knots", type=int, default=0,
                        help="naive.clock_pov_knots_per_step of the brief walk (0: the run's)")
    parser.add_argument("--secant", type=int, default=0,
                        help="naive.clock_pov_secant_calls of the brief walk (0: the run's)")
    args = parser.parse_args()
    arrays = np.load(f"{args.run}/arrays.npz")
    cfg = json.loads(str(arrays["config_json"]))
    if args.knots:
        cfg["naive"]["clock_pov_knots_per_step"] = args.knots
    if args.secant:
        cfg["naive"]["clock_pov_secant_calls"] = args.secant
    world = run_world(cfg)
    params = NaiveParams(**cfg["naive"])
    full, brief = started(NaiveAgent, world, params), started(ClockedAgent, world, params)
    starts = full._phase.to_phase(arrays["povs"][:, 0])
    body = world.body(lights=world.initial_lights)
    rows_full, rows_brief, off, gaps = [], [], [], []
    for state in starts:
        full_samples, full_rows = walk(full, state)
        brief_samples, brief_rows = walk(brief, state)
        if full_samples is None or brief_samples is None:
            continue
        rows_full.append(full_rows)
        rows_brief.append(brief_rows)
        sensed = body.sense(brief._phase.to_body(brief_samples))
        off.append(np.max(np.abs(sensed - sensed[0])) / np.max(np.abs(sensed[0])))
        gaps.append(torus_hausdorff(full_samples, brief_samples))
    gap = np.linalg.norm(_wrap(starts[:, None] - starts[None]), axis=2)
    np.fill_diagonal(gap, np.inf)
    print(json.dumps({
        "walked": len(rows_full), "povs": len(starts),
        "nearest_pov_median": float(np.median(gap.min(axis=1))),
        "rows_full_median": float(np.median(rows_full)),
        "rows_brief_median": float(np.median(rows_brief)),
        "rows_brief_max": int(np.max(rows_brief)),
        "level_set_off_max": float(np.max(off)),
        "hausdorff_median": float(np.median(gaps)), "hausdorff_max": float(np.max(gaps))}))


if __name__ == "__main__":
    main()
