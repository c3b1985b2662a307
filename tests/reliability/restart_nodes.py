"""kill -9 one node of a running smoke graph, restart it, and see whether the
run completes with the undisturbed result:
``python tests/reliability/restart_nodes.py [--nodes agent body ...]``.

For each node: start the five nodes as processes (localhost discovery, a
free domain id), wait until the agent has settled ``--kill-at`` changes, SIGKILL
the node, start it again with the same command line, and wait up to
``--stall-s`` for the representation to finish. Prints one JSON line per node:
completed / stalled / died, equal to the reference or not, and what the bag
(merged by the recorder at SIGTERM) lost of the messages before the kill (see
``bag_losses``).

Every node gets ``graph.checkpoint_dir`` (node_processes.node_parameters) and
the launcher's short-lease Fast DDS profile (dds_environment.graph_environment).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))     # tests/: shared
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import node_processes as np_mod                       # noqa: E402
else:
    from . import node_processes as np_mod

from sensorispace_ros.graph import dds_environment, launcher  # noqa: E402
from sensorispace_ros.graph.framework import PUBLISH_RETRY_S, RESTART_EXIT_CODE  # noqa: E402
from shared import SMOKE  # noqa: E402



class SettledWatcher:
    def __init__(self, domain_id: int):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from sensorispace_ros import contracts
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("restart_watcher", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.settled = -1
        self.received_at: dict[int, float] = {}    # settled k -> monotonic time first seen
        contracts.create_subscription(self.node, "/agent/settled", self.on_settled)

    def on_settled(self, msg) -> None:
        self.settled = max(self.settled, int(msg.data))
        self.received_at.setdefault(int(msg.data), time.monotonic())

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.05, max(0.0, end - time.monotonic())))

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


# Messages the watcher received at least this long before the kill must be in the
# bag when the recorder is the victim: the recorder stores a message within
# milliseconds of its arrival (write-ahead log), this margin covers a recorder
# lagging behind the watcher on a loaded machine.
RECORDER_MARGIN_S = 0.2
# A run that stops settling for this long has stalled: longer than the slowest
# recovery the graph allows itself after a kill, a publish retried for up to
# PUBLISH_RETRY_S, then a command sent again and the body restarted.
NO_PROGRESS_S = 2.0 * PUBLISH_RETRY_S + 10.0


def bag_losses(bag: Path, expected_settled: set[int], expected_changes: set[int]) -> dict:
    """What the (merged) bag lacks: /agent/settled values and /environment/event
    changes expected in it; duplicates are fine."""
    from sensorispace_ros.recording.bag_reader import read_bag_messages

    settled, changes = set(), set()
    for topic, _, _, msg in read_bag_messages(bag, ["/agent/settled", "/environment/event"]):
        if topic == "/agent/settled":
            settled.add(int(msg.data))
        else:
            changes.add(int(msg.header.frame_id.partition("/")[2]))
    return {"settled_missing": sorted(expected_settled - settled),
            "events_missing": sorted(expected_changes - changes),
            "parts_left": sorted(p.name for p in bag.parent.glob(f"{bag.name}.part-*"))}


def restart_run(victim: str, work: Path, kill_at: int, stall_s: float, reference: dict | None,
                write_ahead: bool = True, restart_delay_s: float = 0.0,
                command_timeout_s: float | None = None):
    domain_id = dds_environment.free_domain_id()
    env = dds_environment.graph_environment(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_STATIC_PEERS", None)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    results, bag = work / "results", work / "bag"

    def command(name: str) -> list[str]:
        line = np_mod.command(name, SMOKE, results, bag)
        if name == "recorder" and not write_ahead:
            line += ["-p", "recorder.write_ahead:=false"]
        if name == "agent" and command_timeout_s is not None:
            line += ["-p", f"graph.command_timeout_s:={command_timeout_s}"]
        return line

    processes = np_mod.NodeProcesses(work / "logs")
    watcher = SettledWatcher(domain_id)
    outcome = {"node": victim, "kill_at_settled": kill_at}
    started = time.monotonic()
    try:
        for name in np_mod.NODES:
            processes.start(name, command(name), env)
        while watcher.settled < kill_at:
            watcher.spin(0.1)
            if processes.exited() or time.monotonic() - started > 200:
                outcome["state"] = f"did not reach settled {kill_at}: {processes.exited()}"
                return outcome
        processes.kill9(victim)
        killed_at = time.monotonic()
        outcome["killed_after_s"] = round(killed_at - started, 1)
        outcome["settled_at_kill"] = int(watcher.settled)
        watcher.spin(restart_delay_s)       # the node stays dead this long
        processes.start(victim, command(victim), env,
                        log_name=f"{victim}.restarted")
        deadline = time.monotonic() + stall_s
        last_progress, last_settled = time.monotonic(), watcher.settled
        state = "stalled"
        while time.monotonic() < deadline:
            watcher.spin(0.2)
            if watcher.settled != last_settled:
                last_settled, last_progress = watcher.settled, time.monotonic()
            exited = processes.exited()
            if exited.get("representation") == 0:
                state = "completed"
                outcome["recording_wait_s"] = processes.wait_for_recording(bag)
                break
            dead = {n: c for n, c in exited.items() if n != "representation" or c != 0}
            for name in [n for n, c in dead.items() if c == RESTART_EXIT_CODE]:
                # as the launcher does: a node that asks for it is started again,
                # up to launcher.ASKED_RESTARTS times
                asked = outcome.setdefault("asked_restarts", [])
                if asked.count(name) >= launcher.ASKED_RESTARTS:
                    continue
                asked.append(name)
                processes.start(name, command(name), env,
                                log_name=f"{name}.restart-{len(asked)}")
                del dead[name]
            if dead:
                state = f"died {dead}"
                break
            if time.monotonic() - last_progress > NO_PROGRESS_S and "representation" not in exited:
                state = f"stalled at settled {watcher.settled} (no progress for {NO_PROGRESS_S:.0f} s)"
                break
        outcome["state"] = state
        outcome["settled_at_end"] = int(watcher.settled)
    finally:
        processes.stop()
        watcher.close()
    outcome["wall_s"] = round(time.monotonic() - started, 1)
    if outcome["state"] == "completed" and "killed_after_s" in outcome:
        if victim == "recorder":    # what it had been sent more than the margin before the kill
            expected = {k for k, t in watcher.received_at.items()
                        if t < killed_at - RECORDER_MARGIN_S}
        else:                       # the recorder lived through: everything
            expected = set(range(outcome["settled_at_end"] + 1))
        outcome["bag_expected_settled"] = max(expected, default=-1)
        if victim == "recorder":    # measured, not asserted: the loss window itself
            before_kill = {k: killed_at - t for k, t in watcher.received_at.items()
                           if t < killed_at}
            missing = bag_losses(bag, set(before_kill), set())["settled_missing"]
            outcome["lost_before_kill_ms"] = {k: round(1e3 * before_kill[k], 1) for k in missing}
        # change k's event precedes settle k; the end (settle n + 1) has no event
        outcome["bag"] = bag_losses(bag, expected,
                                    {k for k in expected if 1 <= k < outcome["settled_at_end"]})
    if outcome["state"] == "completed" and reference is not None:
        try:
            np_mod.assert_same_result(np_mod.load_result(results), reference)
            outcome["equals_reference"] = True
        except AssertionError as exc:
            outcome["equals_reference"] = False
            outcome["difference"] = " ".join(str(exc).split())[:200]
    outcome["logs"] = str(processes.log_dir)
    return outcome


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--nodes", nargs="+", default=list(np_mod.NODES))
    parser.add_argument("--kill-at", type=int, default=60, help="agent settled change to kill at")
    parser.add_argument("--stall-s", type=float, default=150.0)
    parser.add_argument("--work", type=Path, default=Path("results/restart"))
    parser.add_argument("--reference", type=Path, default=None)
    parser.add_argument("--command-timeout-s", type=float, default=None,
                        help="the agent's graph.command_timeout_s (re-send period)")
    parser.add_argument("--restart-delay-s", type=float, default=0.0,
                        help="wait this long between the kill and the restart")
    parser.add_argument("--no-write-ahead", action="store_true",
                        help="recorder without its write-ahead log (to measure what it saves)")
    args = parser.parse_args(argv)
    reference = np_mod.load_result(args.reference) if args.reference else None
    for victim in args.nodes:
        outcome = restart_run(victim, args.work / victim, args.kill_at, args.stall_s, reference,
                              write_ahead=not args.no_write_ahead,
                              restart_delay_s=args.restart_delay_s,
                              command_timeout_s=args.command_timeout_s)
        print(json.dumps(outcome), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
