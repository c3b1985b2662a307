"""Wall time of the ROS graph vs the offline naive run, and the round trip per probe.

    PYTHONPATH=. python bench/graph_walltime.py [--config config/smoke.yaml] [--processes]

Offline: ``pipeline.run_naive_strategy`` + ``build_representation`` (what the
graph computes, without evaluation). Graph: every node in one process on one
executor (default) or ``sensorispace launch`` with one process per node
(``--processes``; start-up and evaluation included). Prints both and the
ratio (issue #4 target: <= 1.5), with CPU times next to wall times (the
machine is shared: CPU time is the load-robust number).
"""
import argparse
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--config", default="config/smoke.yaml")
    parser.add_argument("--processes", action="store_true")
    args = parser.parse_args()

    from sensorispace_ros import config, launcher, pipeline
    cfg = config.load_config(args.config)
    started, cpu_started = time.perf_counter(), time.process_time()
    produced = pipeline.run_naive_strategy(cfg, cfg["seed"])
    pipeline.build_representation(produced.povs, produced.pairs, produced.set_ids, cfg,
                                  cfg["seed"])
    offline_s = time.perf_counter() - started
    offline_cpu = time.process_time() - cpu_started
    print(f"offline naive run + representation: {offline_s:.2f} s wall, {offline_cpu:.2f} s CPU "
          f"({len(produced.povs)} POVs, {produced.metrics.get('naive.calls_total')} sense calls)")

    cpu_started = time.process_time()
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    children_before = children.ru_utime + children.ru_stime
    with tempfile.TemporaryDirectory() as tmp:
        if args.processes:
            result = launcher.launch_graph(args.config, "bench", record=False,
                                           results_root=tmp, stream=sys.stdout)
            graph_s = result.wall_s
            mode = "processes (launch: start-up included, evaluation not)"
            round_trip = None
            for line in (result.results_dir / "logs" / "agent.log").read_text().splitlines():
                if "run over" in line:
                    print("agent:", line.split("]: ", 1)[-1])
        else:
            result = launcher.run_graph_in_process(args.config, launcher.free_domain_id(),
                                                   Path(tmp) / "run")
            graph_s = result["wall_s"]
            mode = "one process, one executor"
            body = result["nodes"]["agent"].body
            round_trip = (body.requests, body.round_trip_s)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    graph_cpu = (time.process_time() - cpu_started
                 + children.ru_utime + children.ru_stime - children_before)
    print(f"graph ({mode}): {graph_s:.2f} s wall, {graph_cpu:.2f} s CPU")
    if round_trip:
        print(f"round trips: {round_trip[0]}, {1e3 * round_trip[1] / max(round_trip[0], 1):.3f} ms "
              f"each, {round_trip[1]:.2f} s in total")
    print(f"ratio graph / offline: wall {graph_s / offline_s:.2f}, CPU {graph_cpu / offline_cpu:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
