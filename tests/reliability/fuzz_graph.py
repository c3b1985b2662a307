"""Hostile input for a running smoke graph: ``python tests/reliability/fuzz_graph.py --seconds 60``.

Starts environment, body, agent, representation and recorder as processes
(localhost discovery, a free domain id), then publishes malformed messages on
every topic a node subscribes to, at a bounded rate, for ``--seconds``:

- random bytes in ``data`` (a length that matches no whole number of rows)
- wrong lengths (width, row_step) and wrong field layouts
- NaN / +inf / -inf in a float column
- huge batches (``--huge-rows`` rows, one of them non-finite or mis-sized)
- frame ids outside the protocol grammar, incl. non-ASCII digits ("cmd/²")
- stale (stamp 0) and far-future stamps on all of the above
- body descriptions broken in one way each (frame id, names, periods, sizes)
- exact duplicates of real messages seen earlier on /body/sensation,
  /agent/settled, /agent/points_of_view and /agent/compensations

Every fuzz message breaks the topic contract in at least one way (or is an
exact copy of a real message). Well-formed forgeries (a valid table under a
valid fresh frame id) are out of scope: nothing authenticates publishers
(no SROS2), so a well-formed forgery is indistinguishable from the real thing.
Duplicates on /environment/lights and /body/motor_command are left out by
default (``--duplicate-all`` adds them): measured 2026-11-22, adding them
stalled the run mid-way, cause not yet identified; the body also re-applies an
old change or command.

Reports messages sent per topic, node RSS (start, peak) and whether the result
equals an undisturbed run (the in-process reference run, or ``--reference``).
"""
from __future__ import annotations

import argparse
import array
import json
import os
import sys
import time
from collections import Counter, deque
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))     # tests/: shared
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import node_processes as np_mod                       # noqa: E402
else:
    from . import node_processes as np_mod

from sensorispace_ros import contracts, messages
from sensorispace_ros.core.body_description import BodyDescription
from sensorispace_ros.graph import dds_environment, in_process  # noqa: E402
from shared import SMOKE  # noqa: E402

CLOUD_TOPICS = ("/environment/lights", "/body/motor_command", "/body/sensation",
                "/agent/points_of_view", "/agent/compensations", "/agent/done")
DUPLICATED = ("/body/sensation", "/agent/settled", "/agent/points_of_view",
              "/agent/compensations")
# --duplicate-all adds these (see the module docstring: they stalled the run).
DUPLICATED_TOO = ("/environment/lights", "/body/motor_command")
PAPER_BODY = BodyDescription.revolute(4, 6)     # the smoke run's body
DESCRIPTION = "/body/description"
# (frame id, names, periods, velocity) of descriptions that break the contract
BAD_DESCRIPTIONS = (("rad", ["a"], [1.0], []), ("rad/0", ["a"], [1.0], []),
                    ("deg/" + "9" * 40, ["a"], [1.0], []), ("furlong/6", ["a"], [1.0], []),
                    ("rad/6", [], [], []), ("rad/6", ["a", "a"], [1.0, 1.0], []),
                    ("rad/6", ["a"], [float("nan")], []), ("rad/6", ["a", "b"], [1.0], []),
                    ("rad/6", ["a"], [-1.0], []), ("rad/6", ["a"], [1.0], [0.0]),
                    ("rad/\u00b2", ["a"], [1.0], []))
BAD_FRAMES = ("cmd/²", "change/", "end/x", "cmd/-1", "", "bogus/1", "change/1/2",
              "cmd/" + "9" * 400, "\u202ecmd/1", "change/ 1", "end")


def _subscribed_topics() -> list[str]:
    topics = set()
    for node in ("environment", "body", "agent", "representation"):
        topics.update(contracts.topics_subscribed_by(node))
    return sorted(topics)


# Column types a fuzzed table fills with floats ("number": a sensor's, written as float64).
FLOAT_KINDS = ("float64", "number")

class Fuzzer:
    """A participant of its own that publishes malformed messages on a timer."""

    def __init__(self, domain_id: int, rate_hz: float, seed: int, huge_rows: int,
                 huge_period_s: float = 2.0, duplicate_delay_s: float = 1.0,
                 duplicated=DUPLICATED):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("fuzzer", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.rng = np.random.default_rng(seed)
        self.huge_rows = huge_rows
        self.huge_period_s = huge_period_s
        self.duplicate_delay_s = duplicate_delay_s
        self.topics = _subscribed_topics()
        self.publishers = {t: contracts.create_publisher(self.node, t) for t in self.topics}
        self.sent: Counter = Counter()
        self.kinds: Counter = Counter()
        self.seen: dict[str, deque] = {t: deque(maxlen=50) for t in duplicated}
        self.real_seen: Counter = Counter()
        for topic in duplicated:
            contracts.create_subscription(self.node, topic,
                                          lambda msg, t=topic: self.remember(t, msg))
        self._last_huge = {t: 0.0 for t in self.topics}
        self.duplicates: Counter = Counter()
        self.active = False
        self.timer = self.node.create_timer(1.0 / rate_hz, self.fire)

    def remember(self, topic: str, msg) -> None:
        """Keep real messages (the fuzzer hears its own too: those break the contract)."""
        from sensorispace_ros.graph.framework import parse_frame
        if topic == "/agent/settled":
            real = msg.data < 10 ** 6          # fuzzed settled numbers are >= 10**6
        else:
            try:
                messages.cloud_to_table(msg, contracts.contract(topic).columns_for(PAPER_BODY))
                real = parse_frame(msg.header.frame_id) is not None
            except messages.MessageError:
                real = False
        if real:
            self.real_seen[topic] += 1
            now = time.monotonic()
            # At most 10 kept per second, so the pool reaches back a few seconds
            # even on /body/sensation (hundreds per second).
            if not self.seen[topic] or now - self.seen[topic][-1][0] >= 0.1:
                self.seen[topic].append((now, msg))

    # --------------------------------------------------------------- messages
    def _header(self, frame_id: str):
        stamp = int(self.rng.choice([0, 1, 2 ** 62]))   # stale or far-future stamps
        return messages.make_header(frame_id, stamp)

    def _valid_frame(self, topic: str) -> str:
        kind = {"/body/motor_command": "cmd", "/agent/done": "end"}.get(topic, "change")
        if topic == "/body/sensation":
            kind = str(self.rng.choice(["cmd", "change", "end"]))
        return f"{kind}/{int(self.rng.integers(0, 400))}"

    def _cloud(self, topic: str, rows: int, frame_id: str, nonfinite=None):
        columns = contracts.contract(topic).columns_for(PAPER_BODY)
        table = {}
        for name, kind in columns.items():
            if kind in FLOAT_KINDS:
                table[name] = self.rng.normal(size=rows)
            else:
                table[name] = self.rng.integers(0, 2 ** 16, size=rows)
        if nonfinite is not None:
            float_columns = [n for n, k in columns.items() if k in FLOAT_KINDS]
            name = float_columns[int(self.rng.integers(len(float_columns)))]
            if columns[name] == "number" and np.isnan(nonfinite):
                nonfinite = np.inf           # NaN in a sensor's column is a lost frame
            table[name][int(self.rng.integers(rows))] = nonfinite
        return messages.table_to_cloud(table, columns, self._header(frame_id))

    def malformed(self, topic: str):
        """One message that breaks ``topic``'s contract; returns (kind, message)."""
        if topic == DESCRIPTION:
            return "bad_description", self._description()
        columns = contracts.contract(topic).columns_for(PAPER_BODY)
        has_float = any(k in FLOAT_KINDS for k in columns.values())
        frame_id = self._valid_frame(topic)
        rows = int(self.rng.integers(1, 60))
        now = time.monotonic()
        if now - self._last_huge[topic] >= self.huge_period_s:
            self._last_huge[topic] = now
            if has_float:
                return "huge_nonfinite", self._cloud(topic, self.huge_rows, frame_id, np.nan)
            msg = self._cloud(topic, self.huge_rows, frame_id)
            msg.width += 1                                   # says more rows than it holds
            msg.row_step += msg.point_step
            return "huge_wrong_width", msg
        choices = ["random_bytes", "wrong_width", "bad_fields", "bad_frame"]
        if has_float:
            choices += ["nonfinite"]
        kind = str(self.rng.choice(choices))
        if kind == "nonfinite":
            return kind, self._cloud(topic, rows, frame_id,
                                     float(self.rng.choice([np.nan, np.inf, -np.inf])))
        msg = self._cloud(topic, rows, frame_id)
        if kind == "random_bytes":
            step = msg.point_step
            length = int(self.rng.integers(1, 4000))
            if length % step == 0:
                length += 1
            msg.data = array.array("B", self.rng.bytes(length))
        elif kind == "wrong_width":
            msg.width = int(self.rng.choice([0, rows - 1, rows + 1, 2 ** 31]))
        elif kind == "bad_fields":
            field = msg.fields[int(self.rng.integers(len(msg.fields)))]
            what = int(self.rng.integers(4))
            if what == 0:
                field.name = "bogus"
            elif what == 1:
                field.offset += 1
            elif what == 2:
                field.datatype = 7                           # FLOAT32
            else:
                msg.is_bigendian = True
        else:
            msg.header.frame_id = str(self.rng.choice(BAD_FRAMES))
            # Valid layout and random content: must be refused for the frame id alone.
        return kind, msg

    def _description(self):
        msg = messages.description_to_msg(PAPER_BODY)
        (msg.header.frame_id, msg.name, msg.position, msg.velocity) = BAD_DESCRIPTIONS[
            int(self.rng.integers(len(BAD_DESCRIPTIONS)))]
        return msg

    def fire(self) -> None:
        from std_msgs.msg import UInt64
        if not self.active:
            return
        for topic in self.topics:
            if topic == "/agent/settled":
                kind, msg = "settled_unknown", UInt64(data=int(self.rng.integers(10 ** 6, 2 ** 63)))
            else:
                kind, msg = self.malformed(topic)
            self.publishers[topic].publish(msg)
            self.sent[topic] += 1
            self.kinds[kind] += 1
        for topic, seen in self.seen.items():            # exact duplicates, delayed
            old = [m for t, m in seen if time.monotonic() - t >= self.duplicate_delay_s]
            if old:
                self.publishers[topic].publish(old[int(self.rng.integers(len(old)))])
                self.sent[topic] += 1
                self.kinds["duplicate"] += 1
                self.duplicates[topic] += 1

    def spin_once(self, timeout_s: float) -> None:
        self.executor.spin_once(timeout_sec=timeout_s)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


def run_fuzz(seconds: float, rate_hz: float, work_dir: Path, huge_rows: int = 20000,
             seed: int = 7, finish_timeout_s: float = 400.0, stream=sys.stderr,
             duplicated=DUPLICATED) -> dict:
    """Start the smoke graph, fuzz it for ``seconds`` (starting once every node is up),
    keep fuzzing the nodes still alive until ``seconds`` have passed even if the run
    finished earlier. Returns counts, RSS and the run's result arrays."""
    domain_id = dds_environment.free_domain_id()
    env = dds_environment.graph_environment(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_STATIC_PEERS", None)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    results, bag = Path(work_dir) / "results", Path(work_dir) / "bag"
    processes = np_mod.NodeProcesses(Path(work_dir) / "logs")
    fuzzer = Fuzzer(domain_id, rate_hz, seed, huge_rows, duplicated=duplicated)
    report = {"domain_id": domain_id, "rate_hz_per_topic": rate_hz}
    try:
        for name in np_mod.NODES:
            processes.start(name, np_mod.command(name, SMOKE, results, bag), env)
        deadline = time.monotonic() + 60
        present: set = set()
        while not {"environment", "body", "agent", "representation", "recorder"} <= present:
            if time.monotonic() > deadline:
                raise AssertionError(f"nodes did not appear: {present}")
            fuzzer.spin_once(0.1)
            present = set(fuzzer.node.get_node_names())
        rss_start = processes.rss_mb()
        rss_peak = dict(rss_start)
        fuzzer.active = True
        started = time.monotonic()
        finished_s = None
        died: dict = {}
        while True:
            fuzzer.spin_once(0.01)
            elapsed = time.monotonic() - started
            for name, mb in processes.rss_mb().items():
                rss_peak[name] = max(rss_peak.get(name, 0.0), mb)
            exited = processes.exited()
            if finished_s is None and exited.get("representation") == 0:
                finished_s = elapsed
            died = {n: c for n, c in exited.items() if n != "representation" or c != 0}
            if died:
                break
            if elapsed >= seconds:
                fuzzer.active = False
                if finished_s is not None:
                    break
            if elapsed > seconds + finish_timeout_s:
                break
        alive_at_end = sorted(n for n in np_mod.NODES if n not in processes.exited())
    finally:
        fuzzer.active = False
        processes.stop()
        fuzzer.close()
    report.update({
        "fuzz_s": round(min(seconds, time.monotonic() - started), 1),
        "finished_s": None if finished_s is None else round(finished_s, 1),
        "died": died, "alive_at_end": alive_at_end,
        "sent_per_topic": dict(fuzzer.sent), "sent_by_kind": dict(fuzzer.kinds),
        "duplicates_per_topic": dict(fuzzer.duplicates),
        "real_messages_heard": dict(fuzzer.real_seen),
        "rss_start_mb": {k: round(v, 1) for k, v in rss_start.items()},
        "rss_peak_mb": {k: round(v, 1) for k, v in rss_peak.items()},
        "logs": str(processes.log_dir),
    })
    report["result"] = np_mod.load_result(results) if finished_s is not None else None
    print("fuzz: " + json.dumps({k: v for k, v in report.items() if k != "result"}),
          file=stream, flush=True)
    return report


def rss_bounded(report: dict) -> dict:
    """Nodes whose peak RSS broke the bound 2 x start + 200 MB (empty if none)."""
    return {n: (report["rss_start_mb"][n], peak) for n, peak in report["rss_peak_mb"].items()
            if n in report["rss_start_mb"] and peak > 2 * report["rss_start_mb"][n] + 200}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--rate", type=float, default=5.0,
                        help="malformed messages per second per topic (default 5)")
    parser.add_argument("--huge-rows", type=int, default=20000)
    parser.add_argument("--work", type=Path, default=Path("results/fuzz"))
    parser.add_argument("--duplicate-all", action="store_true",
                        help="also re-publish old lights and motor commands (see the docstring)")
    parser.add_argument("--reference", type=Path, default=None,
                        help="a results dir holding representation.npz of an undisturbed run "
                             "(default: run one in-process first)")
    args = parser.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    if args.reference is None:
        args.reference = args.work / "reference"
        t0 = time.monotonic()
        in_process.run_graph_in_process(SMOKE, dds_environment.free_domain_id(), args.reference,
                                        timeout_s=400)
        print(f"reference run: {time.monotonic() - t0:.1f} s", file=sys.stderr)
    reference = np_mod.load_result(args.reference)
    report = run_fuzz(args.seconds, args.rate, args.work / "fuzzed", args.huge_rows,
                      duplicated=DUPLICATED + (DUPLICATED_TOO if args.duplicate_all else ()))
    verdicts = {"no_node_died": not report["died"],
                "rss_bounded": not rss_bounded(report),
                "finished": report["result"] is not None}
    if report["result"] is not None:
        try:
            np_mod.assert_same_result(report["result"], reference)
            verdicts["result_unchanged"] = True
        except AssertionError as exc:
            verdicts["result_unchanged"] = False
            print(f"result differs: {exc}", file=sys.stderr)
    print("verdicts: " + json.dumps(verdicts))
    return 0 if all(verdicts.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
