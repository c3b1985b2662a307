"""The naive strategy end to end on a body with imperfections no parameter names.

The agent gets the simulator through a wrapper of its ``sense`` that adds
what a real sensor or motor does (``ImperfectSensing``,
tests/core/imperfect_bodies.py): Gaussian or
Laplace noise on each receptor, noise proportional to the signal, float32
rounding, quantisation, lost rows (NaN) and joints that land off the
commanded state. The agent is never told which. Writes the run's
metrics.json like ``sensorispace reproduce`` (figures off)::

    .venv/bin/python bench/noisy_naive.py --config config/smoke.yaml --seed 0 \\
        --noise 1e-3 --out /tmp/noisy
    .venv/bin/python bench/noisy_naive.py --config config/paper.yaml --quantum 4e-3 ...

and prints the headline numbers (POVs, coverage, wrong poses, affine
residual, queries, wall time) as one JSON line.
"""
from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from pathlib import Path

from sensorispace_ros import config as config_mod
from sensorispace_ros.core import clocked_run

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "core"))
from imperfect_bodies import ImperfectSensing  # noqa: E402  (a test helper, shared)


def run(config: str, seed: int, out: str, **imperfections) -> dict:
    from sensorispace_ros.evaluation.reproduce import reproduce

    cfg = config_mod.load_config(config)
    wrapper = functools.partial(ImperfectSensing, seed=seed + 7919, **imperfections)
    # The offline strategy reaches run_naive through clocked_run's own binding:
    # patch that one, and put it back, so that runs in one process keep apart.
    original = clocked_run.run_naive
    clocked_run.run_naive = functools.partial(original, body_wrapper=wrapper)
    started = time.perf_counter()
    try:
        metrics = reproduce(cfg, "naive", seed, out, figures=False)
    finally:
        clocked_run.run_naive = original
    flat = config_mod.flatten(metrics)
    keys = ("pov.count", "naive.coverage", "naive.coverage_of_paper_positions",
            "naive.wrong_poses", "naive.state_changes_accepted",
            "naive.pose_rank", "naive.pov_dim", "naive.space_dim", "naive.noise_estimate",
            "naive.queries_per_pov", "naive.queries_total", "naive.fd_step")
    summary = {k: flat.get(k) for k in keys}
    summary.update({k: v for k, v in flat.items() if "affine" in k and "after" in k})
    summary["wall_s"] = round(time.perf_counter() - started, 1)
    summary["imperfections"] = imperfections
    return summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", default="config/smoke.yaml")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="/tmp/noisy_naive")
    for name in ("noise", "laplace", "relative", "quantum", "motor_noise", "dropout"):
        parser.add_argument(f"--{name}", type=float, default=0.0)
    parser.add_argument("--float32", action="store_true")
    args = vars(parser.parse_args())
    summary = run(args.pop("config"), args.pop("seed"), args.pop("out"),
                  **{k: v for k, v in args.items() if v})
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
