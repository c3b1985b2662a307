"""Where the graph's time goes: each step of a round trip and of a hand-over.

    PYTHONPATH=. python bench/graph_hops.py [--config config/paper.yaml] [--json OUT]

Launches the graph (one process per node, no recorder) with
``SENSORISPACE_TRACE_DIR`` set, so every node stamps its steps
(``sensorispace_ros.graph.tracing``), then prints per step the count, mean, median,
90th percentile and total: for the agent's commands (publish -> the body's
callback -> its answer's publication -> the agent's callback -> back in its
computation) and for the changes (the rest command's answer -> settle ->
environment -> lights -> body -> passive sensation -> the agent's reaction),
then how long the agent sits idle, its next sweep sent, before each passive
sensation is published, and that sensation's hop to the idle agent
(``tracing.idle_waits``).
One machine's numbers are in docs/benchmarks.md; ``graph_walltime.py``
gives the wall time against the offline run.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

from sensorispace_ros.graph import tracing  # noqa: E402


def report(events) -> dict:
    """Both step tables of ``events`` (``tracing.load``) and their totals."""
    trips, changes = tracing.round_trips(events), tracing.hand_overs(events)
    return {"round_trips": len(trips), "round_trip": tracing.step_table(trips, tracing.ROUND_TRIP),
            "changes": len(changes), "hand_over": tracing.step_table(changes, tracing.HAND_OVER),
            "agent_idle": tracing.idle_waits(events)}


def print_table(title: str, count: int, rows: list[dict]) -> None:
    total = sum(r["mean_us"] for r in rows)
    print(f"{title}: {count} complete; mean {total:.0f} us in all")
    print(f"  {'step':52s} {'mean':>7s} {'median':>7s} {'p90':>7s} {'total':>8s}")
    for r in rows:
        step = f"{r['from']} -> {r['to']}"
        print(f"  {step:52s} {r['mean_us']:5.0f}us {r['median_us']:5.0f}us "
              f"{r['p90_us']:5.0f}us {r['total_s']:7.2f}s")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default=str(HERE.parent / "config" / "paper.yaml"))
    parser.add_argument("--json", type=Path, default=None, help="also write the tables here")
    parser.add_argument("--traces", type=Path, default=None,
                        help="analyse the stamps already in this directory (no run)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        traces = args.traces
        if traces is None:
            from sensorispace_ros.graph import launcher
            traces = Path(tmp) / "traces"
            os.environ[tracing.TRACE_DIR_ENV] = str(traces)
            try:
                result = launcher.launch_graph(args.config, "hops", record=False,
                                               results_root=Path(tmp) / "results")
            finally:
                del os.environ[tracing.TRACE_DIR_ENV]
            if result.exit_code != 0:
                print(f"graph run failed: {result.message}", file=sys.stderr)
                return 1
            print(f"graph: {result.wall_s:.1f} s wall")
        events = tracing.load(traces)
        if not events:
            print(f"no stamps in {traces}", file=sys.stderr)
            return 1
        tables = report(events)
    print_table("round trips (commands the agent waited for)", tables["round_trips"],
                tables["round_trip"])
    print_table("hand-overs (changes)", tables["changes"], tables["hand_over"])
    idle = tables["agent_idle"]
    for key, what in (("idle_before_passive", "the agent idle (its next sweep sent) until the "
                       "passive sensation is published"),
                      ("passive_hop_when_idle", "that sensation's hop to the idle agent")):
        r = idle[key]
        if r["n"]:
            print(f"  {what}: mean {r['mean_us']:.0f} us, median {r['median_us']:.0f} us, "
                  f"p90 {r['p90_us']:.0f} us ({r['n']} changes)")
    print(f"  the agent was idle first in {100 * idle['idle_first_share']:.0f} % of the changes")
    if args.json is not None:
        args.json.write_text(json.dumps(tables, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
