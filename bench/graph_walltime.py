"""Wall time of the ROS graph vs the offline naive run, and the round trip per probe.

    PYTHONPATH=. python bench/graph_walltime.py [--config config/smoke.yaml] [--processes]
        [--repeat N]

Both sides do the same work and are timed the same way (target: graph <=
1.5x offline):

* offline: a fresh Python process (``--offline-child``) that imports the
  project, builds the world, steps the naive agent through the schedule
  (``core.naive.run.explore_naive``) and builds the representation
  (``offline.representation.build_representation``), timed from its spawn to its exit. No
  ground-truth evaluation: its join (``evaluation.naive.join_naive_run``)
  also runs the paper strategy for the coverage denominator, which the
  graph does after its clock stops.
  ``--legacy-offline`` also prints ``run_naive_strategy`` and that join
  timed in this process (imports excluded, evaluation included).
* graph: every node in one process on one executor (default) or ``sensorispace
  launch`` with one process per node (``--processes``: node start-up
  included, evaluation not).

Prints both, the ratio, and CPU times next to wall times (the machine is
shared: CPU time is the load-robust number).
"""
import argparse
import json
import os
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

from bench.child import child_environment, run_measured  # noqa: E402


def offline_child(config_path: str) -> int:
    """The offline run, in this (fresh) process; prints its stage times as JSON."""
    started = time.perf_counter()
    from sensorispace_ros import config
    from sensorispace_ros.offline.representation import build_representation
    from sensorispace_ros.core.run_world import run_world
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.naive.run import explore_naive
    imported = time.perf_counter()
    cfg = config.load_config(config_path)
    world = run_world(cfg)
    explored = explore_naive(world, NaiveParams(**cfg["naive"]))
    agent = explored.agent
    pairs, set_ids = agent.equality_sets()
    explored_at = time.perf_counter()
    build_representation(agent.points_of_view, pairs, set_ids, cfg, cfg["seed"])
    done = time.perf_counter()
    print(json.dumps({"import_s": imported - started, "exploration_s": explored_at - imported,
                      "representation_s": done - explored_at,
                      "points_of_view": len(agent.points_of_view),
                      "calls": agent.calls_total}))
    return 0


def run_offline(config_path: str) -> dict:
    """Spawn ``offline_child`` (``bench.child.run_measured``); its wall time from
    spawn to exit, CPU time and stages."""
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "offline.log"
        measured = run_measured([sys.executable, str(HERE / "graph_walltime.py"),
                                 "--offline-child", "--config", config_path], log_path=log,
                                env=child_environment())
        output = log.read_text()
    if measured["exit_code"] != 0:
        raise SystemExit(f"offline child failed (exit {measured['exit_code']}):\n"
                         f"{output[-2000:]}")
    stages = json.loads([line for line in output.splitlines() if line.startswith("{")][-1])
    return {"wall_s": measured["wall_s"], "cpu_s": measured["cpu_s"], **stages}


def legacy_offline(config_path: str) -> float:
    """The in-process offline number: ``run_naive_strategy`` (ground-truth
    evaluation included) + representation, in this process, imports excluded."""
    from sensorispace_ros import config
    from sensorispace_ros.offline.representation import build_representation
    from sensorispace_ros.evaluation.ground_truth import RunTruth
    from sensorispace_ros.evaluation.naive import join_naive_run
    from sensorispace_ros.offline.strategies import run_naive_strategy
    cfg = config.load_config(config_path)
    started = time.perf_counter()
    produced = run_naive_strategy(cfg, cfg["seed"])
    join_naive_run(produced, RunTruth(cfg, produced.world))
    build_representation(produced.povs, produced.pairs, produced.set_ids, cfg, cfg["seed"])
    return time.perf_counter() - started


def run_pair(args, legacy: bool = False) -> float:
    """One offline run, then one graph run; prints both and returns the wall ratio."""
    offline = run_offline(args.config)
    print(f"offline naive run + representation (fresh process, no ground truth): "
          f"{offline['wall_s']:.2f} s wall, {offline['cpu_s']:.2f} s CPU (imports "
          f"{offline['import_s']:.2f} s, exploration {offline['exploration_s']:.2f} s, "
          f"representation {offline['representation_s']:.2f} s; "
          f"{offline['points_of_view']} POVs, {offline['calls']} sense calls)")
    if legacy:
        print(f"legacy offline number (run_naive_strategy in-process, ground truth included): "
              f"{legacy_offline(args.config):.2f} s")

    from sensorispace_ros.graph import dds_environment, in_process, launcher
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
                if "run over" in line or "transport:" in line:
                    print("agent:", line.split("]: ", 1)[-1])
        else:
            result = in_process.run_graph_in_process(args.config, dds_environment.free_domain_id(),
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
    print(f"ratio graph / offline: wall {graph_s / offline['wall_s']:.2f}, "
          f"CPU {graph_cpu / offline['cpu_s']:.2f}")
    return graph_s / offline["wall_s"]


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--config", default="config/smoke.yaml")
    parser.add_argument("--processes", action="store_true")
    parser.add_argument("--legacy-offline", action="store_true",
                        help="also time run_naive_strategy in this process (imports excluded, "
                             "evaluation included)")
    parser.add_argument("--repeat", type=int, default=1,
                        help="offline/graph pairs to run, alternated (the host's noise moves a "
                             "single ratio by ~0.15 on paper.yaml)")
    parser.add_argument("--offline-child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.offline_child:
        return offline_child(args.config)
    if args.repeat < 1:
        parser.error("--repeat: must be >= 1")

    ratios = []
    for pair in range(args.repeat):
        if args.repeat > 1:
            print(f"pair {pair + 1}/{args.repeat}: load {[round(v, 2) for v in os.getloadavg()]}")
        ratios.append(run_pair(args, legacy=args.legacy_offline and pair == 0))
    if len(ratios) > 1:
        print("wall ratios: " + ", ".join(f"{r:.2f}" for r in ratios)
              + f"; median {statistics.median(ratios):.2f}, worst {max(ratios):.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
