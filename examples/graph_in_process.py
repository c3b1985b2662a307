"""A run of the ROS 2 graph in this process, then its evaluation.

Environment, body, agent and representation nodes spin on one executor in a
private rclpy Context, on a free domain with localhost-only discovery
(``graph.in_process.run_graph_in_process``); the representation node writes
its arrays and the agent its records into ``RESULTS``. The evaluator joins
them with the ground truth of the run's configuration
(``evaluation.graph_run.evaluate_representation``) and writes metrics.json and
arrays.npz there. Needs the ROS 2 wheels of the venv (no bag, no launcher).

    .venv/bin/python examples/graph_in_process.py [config/smoke.yaml] [results/in-process]
"""
from __future__ import annotations

import sys
from pathlib import Path

from sensorispace_ros import config
from sensorispace_ros.evaluation.graph_run import evaluate_representation
from sensorispace_ros.graph.dds_environment import free_domain_id
from sensorispace_ros.graph.in_process import run_graph_in_process

REPO = Path(__file__).resolve().parents[1]


def main(config_path: str | Path = REPO / "config" / "smoke.yaml",
         results: str | Path = "results/in-process") -> dict:
    results = Path(results)
    run = run_graph_in_process(config_path, free_domain_id(), results, timeout_s=600)
    cfg = config.load_config(config_path, {"output.figures": False})
    metrics = evaluate_representation(results, cfg)
    naive = metrics["naive"]
    print(f"graph run: {run['wall_s']:.1f} s, {metrics['pov']['count']} points of view; "
          f"coverage {naive['coverage']:.2f} ({naive['distinct_positions']} of "
          f"{naive['paper_positions']} positions the paper strategy compensates)")
    return metrics


if __name__ == "__main__":
    main(*sys.argv[1:3])
