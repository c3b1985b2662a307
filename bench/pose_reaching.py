"""Reaching in pose space re-measured from runs' arrays with more pairs.

A run's ``pose_reaching.*`` uses the config's ``representation.reaching.pairs``
(30 in the rotation configs); this re-evaluates the same graphs on ``--pairs``
pairs (the ``reaching`` stream of the run's seed), with the angle coordinate
recomputed from the run's metric and equality sets, and prints one line per
graph: pose-space straightness median and p90, reached share, long-way share,
and the angle coordinate's short-way share and turn error.

    PYTHONPATH=. .venv/bin/python bench/pose_reaching.py /tmp/x --pairs 300
"""
from __future__ import annotations

import argparse
import json

import numpy as np

from sensorispace_ros.evaluation.pose_reaching import pose_reaching_numbers
from sensorispace_ros.evaluation.rotations import angle_numbers
from sensorispace_ros.evaluation.run_files import ARRAYS_FILE, representation_from_arrays


def measure(run_dir: str, pairs: int) -> dict:
    arrays = dict(np.load(f"{run_dir}/{ARRAYS_FILE}"))
    cfg = json.loads(str(arrays["config_json"]))
    cfg["representation"]["reaching"]["pairs"] = pairs
    representation = representation_from_arrays(arrays)
    _, angle = angle_numbers(representation.distance, arrays["true_poses"], arrays["pairs"],
                             arrays["set_ids"])
    return pose_reaching_numbers(representation, arrays["true_poses"], cfg,
                                 int(arrays["seed"]), angle)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", help="run directories (metrics.json, arrays.npz)")
    parser.add_argument("--pairs", type=int, default=300)
    args = parser.parse_args()
    for run_dir in args.runs:
        numbers = measure(run_dir, args.pairs)
        print(f"{run_dir}: {args.pairs} pairs, length scale {numbers['pose_reaching.length_scale']}")
        graphs = sorted({key.split(".")[1] if key.count(".") == 2 else
                         ".".join(key.split(".")[1:3]) for key in numbers
                         if key.endswith(".straightness_median")})
        for graph in graphs:
            p = f"pose_reaching.{graph}."
            print(f"  {graph:10s} median {numbers[p + 'straightness_median']:.2f}  p90 "
                  f"{numbers[p + 'straightness_p90']:.2f}  reached {numbers[p + 'reached_share']:.2f}"
                  f"  long way {numbers[p + 'long_way_share']:.2f}")
        if "pose_reaching.angle.short_way_share" in numbers:
            print(f"  angle: short way {numbers['pose_reaching.angle.short_way_share']:.3f} of "
                  f"{numbers['pose_reaching.angle.scored']}, turn error median "
                  f"{numbers['pose_reaching.angle.turn_error_median']:.4f} rad")


if __name__ == "__main__":
    main()
