"""How well the naive agent measures its own noise: ``noise.measure_noise``
over many noise draws, against the true sd.

For each body (the test suite's smooth two-joint body, the paper's eye at
seed 0's start) and each kind of noise (Gaussian, Laplace: sd ``b * sqrt(2)``),
one ``measure_noise`` per draw; prints one JSON line per case: the estimate
over the true sd (mean, sd, 2.5 and 97.5 percentiles), and the same for the
larger of the two robust spreads alone (``repeat_sd``, ``ladder_sd`` as
``noise_spread.repeat_spread`` and ``ladder_spread`` read them, the rule
where repeats and ladder disagree), and the share of draws pooled::

    .venv/bin/python bench/noise_estimate.py --draws 300

Diagnostics only: nothing here is the agent's.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from sensorispace_ros import config as config_mod
from sensorispace_ros.core.naive.noise import measure_noise
from sensorispace_ros.core.naive.noise_spread import (ladder_spread, ladder_steps, noise_rows,
                                                      random_noise, repeat_spread)
from sensorispace_ros.core.run_world import run_world

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "core"))
from imperfect_bodies import ImperfectSensing, SmoothBody  # noqa: E402  (a test helper, shared)

REPEATS = 16


def _summary(ratios) -> dict:
    r = np.asarray(ratios)
    return {"mean": round(float(r.mean()), 3), "sd": round(float(r.std()), 3),
            "p2.5": round(float(np.percentile(r, 2.5)), 3),
            "p97.5": round(float(np.percentile(r, 97.5)), 3)}


def measure(make_body, center, kind: str, scale: float, draws: int) -> dict:
    true_sd = scale * (np.sqrt(2.0) if kind == "laplace" else 1.0)
    estimates, larger, pooled = [], [], 0
    for seed in range(draws):
        estimates.append(measure_noise(ImperfectSensing(make_body(), seed=seed, **{kind: scale}),
                                       center, repeats=REPEATS, line_rows=REPEATS).sd)
        body = ImperfectSensing(make_body(), seed=seed, **{kind: scale})
        sensed = np.asarray(body.sense(noise_rows(center, REPEATS, REPEATS)))
        repeats = sensed[:REPEATS]
        lines = sensed[REPEATS:].reshape(len(ladder_steps()), REPEATS, -1)
        larger.append(max(repeat_spread(repeats), ladder_spread(lines)))
        pooled += random_noise(repeats, lines) is not None
    return {"estimate / true": _summary(np.array(estimates) / true_sd),
            "larger robust spread / true": _summary(np.array(larger) / true_sd),
            "pooled share": round(pooled / draws, 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--draws", type=int, default=300)
    parser.add_argument("--sd", type=float, default=1e-3)
    args = parser.parse_args()
    world = run_world(config_mod.load_config("config/paper.yaml"), 0)
    bodies = {"smooth two-joint body": (SmoothBody, np.array([0.3, -0.7])),
              "paper eye, seed 0 start": (lambda: world.body(lights=world.initial_lights),
                                          world.m0)}
    for name, (make_body, center) in bodies.items():
        for kind in ("noise", "laplace"):
            print(json.dumps({"body": name, "noise": kind, "scale": args.sd,
                              **measure(make_body, center, kind, args.sd, args.draws)}))


if __name__ == "__main__":
    main()
