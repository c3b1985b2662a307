"""Wall time of the graph on the row clock against the lockstep graph.

    PYTHONPATH=. python bench/clock_graph_walltime.py [--config config/smoke.yaml]
        [--interval 2000] [--repeat N] [--processes]

Both runs are the whole graph in one process (``graph.in_process``), each in
a fresh Python process, timed from the nodes' start to the representation
written (``wall_s``), or with ``--processes`` ``sensorispace launch`` (one
process per node, start-up included, no bag, no evaluation); ``world.clock: agent`` against ``world.clock: rows`` with
mean interval ``--interval`` (target: rows <= 1.5x lockstep). Pairs alternate;
prints each pair, the median and worst ratio.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
HERE = Path(__file__).resolve().parent


def child(config_path: str, clock: str, interval: float, domain_id: int,
          processes: bool = False) -> int:
    sys.path.insert(0, str(HERE.parent))
    from sensorispace_ros import config
    from sensorispace_ros.graph import in_process, launcher
    with tempfile.TemporaryDirectory() as tmp:
        cfg = config.load_config(config_path, overrides={"world.clock": clock,
                                                         "world.change_interval": interval})
        path = Path(tmp) / "cfg.yaml"
        path.write_text(config.to_parameter_file(cfg))
        if processes:
            result = launcher.launch_graph(path, "bench", record=False, results_root=tmp,
                                           stream=sys.stderr)
            print(json.dumps({"wall_s": result.wall_s}))
            return 0
        result = in_process.run_graph_in_process(path, domain_id, Path(tmp) / "run",
                                                 timeout_s=3600)
        agent = result["nodes"]["agent"]
        print(json.dumps({"wall_s": result["wall_s"], "commands": agent.body.requests,
                          "queries": agent.agent.queries_total,
                          "povs": len(agent.agent.points_of_view)}))
    return 0


def measure(config_path: str, clock: str, interval: float, domain_id: int,
            processes: bool) -> dict:
    out = subprocess.run([sys.executable, __file__, "--child", clock, "--config", config_path,
                          "--interval", str(interval), "--domain-id", str(domain_id)]
                         + (["--processes"] if processes else []),
                         check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--config", default="config/smoke.yaml")
    parser.add_argument("--interval", type=float, default=2000.0)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--domain-id", type=int, default=77)
    parser.add_argument("--processes", action="store_true")
    parser.add_argument("--child", choices=("agent", "rows"))
    args = parser.parse_args()
    if args.child:
        return child(args.config, args.child, args.interval, args.domain_id, args.processes)
    ratios = []
    for _ in range(args.repeat):
        lockstep = measure(args.config, "agent", args.interval, args.domain_id, args.processes)
        rows = measure(args.config, "rows", args.interval, args.domain_id, args.processes)
        ratios.append(rows["wall_s"] / lockstep["wall_s"])
        print(f"lockstep {lockstep}  rows {rows}  ratio {ratios[-1]:.2f}", flush=True)
    print(f"rows / lockstep: median {statistics.median(ratios):.2f}, worst {max(ratios):.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
