"""Agent node: the naive agent (core.naive.agent.NaiveAgent, unchanged).

It subscribes to ``/body/sensation`` and ``/body/description`` and nothing
else. It starts once the body has said what it is (the latched
``/body/description``): its motor commands have one column per joint, its
sensations one per receptor, and the naive agent is sized from that, never
from the configuration; sensations that come before the description wait
for it. It meets its body through ``graph.body_over_topics.BodyOverTopics`` (a ``sense`` is a round trip
of ``/body/motor_command`` and ``/body/sensation``, spun in this thread; with
each settle it sends the next change's first call ahead). Commands and answers
travel as serialized bytes (``messages.CloudCdrPacker`` /
``GraphNode.read_float_cloud``).

Passive sensations (``change/<k>``) are queued by the subscription callback;
``step()``, called by the spinning loop between callbacks (never inside
one), lets the agent react, publishes the new points of view and equality
rows, then ``/agent/settled`` = k. ``end/<k>`` ends the run:
``/agent/done`` carries the totals.

For the evaluator (recorded, read by ``sensorispace analyze``) it also
publishes its own bookkeeping, never anything of the world:
``/agent/pov_records`` (event and walk queries of each POV),
``/agent/compensation_records`` (each accepted compensation) and, at the
end, ``/agent/stage_counters``: together ``core.naive.records.
NaiveAgentRecords``, the data the offline run is evaluated from. At the end
it also writes them to ``<graph.results_dir>/agent_records.npz``, for a run
evaluated without a bag (``launch --no-record``).

Restart (only with ``graph.checkpoint_dir`` set, "" costs nothing).
The checkpoint is read and checked at start-up (a bad one stops the node
there), and resumed once the body description has come. The agent persists ``<dir>/agent.snapshot`` and ``<dir>/agent.journal``
(format: ``sensorispace_ros.state.agent_journal``). The journal gets, unbuffered
(one ``os.writev`` each, kept by the page cache through a kill -9), every
input the agent consumes: each new passive sensation when it arrives, each
body answer (with a crc of the command it answers), and a marker once a
change's reaction is published. At an event boundary (after
``/agent/settled`` k), at most every ``snapshot_period_s`` of wall time and
every 100 times the last snapshot's duration, the snapshot is replaced
atomically (``NaiveAgent.state()`` plus the node's counters and
queued passives) and the journal emptied. A restarted agent loads the
snapshot, re-feeds the journal through the deterministic NaiveAgent (answers
come from the journal, checked by command number and crc) and publishes the
replayed reactions again (what a killed process published last may never
have left it; the representation ignores duplicates, the analysis takes the
first copy; the snapshot waits until its publishers' messages are
acknowledged before it empties the journal), settling only changes without
a marker; where the journal ends mid-change, it continues live: its next
command carries the same ``cmd/<n>`` as the one the dead agent sent (the body
answers duplicates identically).
Before its first publication it waits (<= 5 s) until the body's and the
environment's subscriptions have matched (earlier messages are lost).
Until the first new passive sensation arrives, whenever it is idle on a
settled change it re-publishes that settle every ``graph.resend_period_s``
(the settle, or the passive sensation that followed it, may have been lost
while it was dead; the environment answers a repeated settle of the change
before its current one with the current lights). ``/agent/done`` totals, POVs,
equality rows and records equal those of an undisturbed run. The snapshot is
a pickle: the checkpoint directory must be as trusted as the code.

Retransmit: a command unanswered after ``graph.command_timeout_s`` is
published again with the same frame id (``BodyOverTopics``); a late
duplicate answer is dropped. A passive sensation of the change the agent
last settled makes it publish that settle again (a restarted environment
re-sends its current change when the settle may have been lost).
"""
from __future__ import annotations

import collections
import time
from pathlib import Path

import numpy as np
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from std_msgs.msg import UInt64

from sensorispace_ros import config, contracts, messages
from sensorispace_ros.graph import tracing
from sensorispace_ros.graph.body_over_topics import BodyOverTopics, RunAborted
from sensorispace_ros.state.agent_journal import (JOURNAL_FILE, SNAPSHOT_FILE, AgentJournal,
    CheckpointError, read_journal, read_snapshot, write_snapshot)
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.records import STAGES as NAIVE_STAGES
from sensorispace_ros.core.naive.records import (STRUCTURE_FIELDS, NaiveAgentRecords,
                                                 structure_fields)
from sensorispace_ros.graph.framework import GraphNode, frame, run_node
from sensorispace_ros.protocol import AGENT_RECORDS_FILE

TOPICS = ("/body/motor_command", "/body/sensation", "/agent/points_of_view",
          "/agent/compensations", "/agent/done", "/agent/pov_records",
          "/agent/compensation_records", "/agent/stage_counters")


class AgentNode(GraphNode):

    # Wall time between two snapshots (each is written at an event boundary
    # and empties the journal), and at least snapshot_cost_factor times the
    # last snapshot's own duration, so snapshots take <= 1 % of the run
    # (measured: 0.3 MB / ~2 ms on smoke.yaml, 5-7 MB / 60-160 ms a quarter
    # into paper.yaml, growing with the equality sets).
    snapshot_period_s = 5.0
    snapshot_cost_factor = 100.0

    def __init__(self, **kwargs):
        super().__init__("agent", **kwargs)
        self.columns: dict[str, dict] = {}
        self.command_pub = contracts.create_publisher(self, "/body/motor_command")
        # Commands go out and answers come in as serialized bytes (messages.CloudCdrPacker,
        # GraphNode.read_float_cloud): rclpy's message conversions would cost more
        # than the rest of a round trip, once per sense call each way.
        self.command_packer: messages.CloudCdrPacker | None = None
        self.pov_pub = contracts.create_publisher(self, "/agent/points_of_view")
        self.compensation_pub = contracts.create_publisher(self, "/agent/compensations")
        self.settled_pub = contracts.create_publisher(self, "/agent/settled")
        self.done_pub = contracts.create_publisher(self, "/agent/done")
        self.pov_record_pub = contracts.create_publisher(self, "/agent/pov_records")
        self.compensation_record_pub = contracts.create_publisher(
            self, "/agent/compensation_records")
        self.stage_counter_pub = contracts.create_publisher(self, "/agent/stage_counters")
        contracts.create_subscription(
            self, "/body/sensation", self.when_described("/body/sensation", self.on_sensation),
            raw=True)
        # Sized by the body description (start_body).
        self.body: BodyOverTopics | None = None
        self.agent: NaiveAgent | None = None
        self.initial_motor_state: np.ndarray | None = None
        self.aborted = False
        self.passive: collections.deque = collections.deque()
        self.last_passive = -1
        self.last_settled = -1
        self.settles_resent = 0
        self.late_answers = 0
        self.predecessor_sent = 0
        self.n_povs = 0
        self.n_rows = 0
        self.run_over = False
        self.finished = False
        self.exit_code = 0
        self._stepping = False
        # Restart (see the module docstring).
        self.journal: AgentJournal | None = None
        self.published_before_restart: set[int] = set()
        self.checkpoint_stats = {"snapshots": 0, "snapshot_bytes": 0, "snapshot_s": 0.0,
                                 "last_snapshot_s": 0.0, "replayed_passives": 0,
                                 "ack_timeouts": 0}
        self._last_snapshot = time.monotonic()
        self._resume_timer = None
        self._await_peers = False
        self.checkpoint = None
        if self.graph["checkpoint_dir"]:
            try:
                self.checkpoint = self.read_checkpoint(Path(self.graph["checkpoint_dir"]))
            except (CheckpointError, OSError) as exc:
                # run_node turns this into one line and exit code 2, no traceback.
                raise config.ConfigError(f"graph.checkpoint_dir: {exc}") from exc
        self.subscribe_description(self.start_body)

    def start_body(self, description) -> None:
        """Size the agent from the body description: its commands, its sensations,
        the naive agent; then resume from the checkpoint, if any."""
        self.columns = {topic: self.columns_of(topic) for topic in TOPICS}
        self.command_packer = messages.CloudCdrPacker(self.columns["/body/motor_command"])
        self.body = BodyOverTopics(self.publish_command, lambda t: self.spin_once(t),
                                   n_motors=description.n_motors,
                                   n_sensors=description.receptors,
                                   command_timeout_s=float(self.graph["command_timeout_s"]),
                                   on_retransmit=self.log_retransmit, description=description)
        self.body.aborted = self.aborted
        self.initial_motor_state = self.initial_posture(description)
        self.agent = NaiveAgent(self.body, NaiveParams(**self.cfg["naive"]))
        if self.checkpoint is not None:
            checkpoint, self.checkpoint = self.checkpoint, None
            try:
                self.restore(*checkpoint)
            except CheckpointError as exc:
                self.get_logger().error(f"graph.checkpoint_dir: {exc}")
                self.exit_code = 2
                self.finished = True

    def initial_posture(self, description) -> np.ndarray:
        """The agent's first motor state (proprioception, nothing of the world):
        ``arm.initial_motor_state`` when it has a value per joint of this body
        (the simulated body starts there), otherwise every joint at 0."""
        posture = np.asarray(self.cfg["arm"]["initial_motor_state"], float)
        if posture.shape == (description.n_motors,):
            return posture
        self.get_logger().warning(
            f"arm.initial_motor_state has {len(posture)} values for a body of "
            f"{description.n_motors} joints: starting with every joint at 0")
        return np.zeros(description.n_motors)

    # ------------------------------------------------------------ restart

    def read_checkpoint(self, directory: Path) -> tuple:
        """The snapshot and the journal of ``directory`` (none: a fresh start),
        read and checked against this run's configuration."""
        snapshot_path = directory / SNAPSHOT_FILE
        snapshot = read_snapshot(snapshot_path)
        if snapshot is not None and snapshot.get("config") != self.cfg:
            raise CheckpointError(f"{snapshot_path}: written by a run with another "
                                  "configuration; remove it to start afresh")
        return directory, snapshot, read_journal(directory / JOURNAL_FILE)

    def restore(self, directory: Path, snapshot, journal) -> None:
        """Resume from ``read_checkpoint``'s snapshot and journal, and open the
        journal for appending."""
        snapshot_path = directory / SNAPSHOT_FILE
        if snapshot is not None:
            if snapshot.get("description", self.description) != self.description:
                raise CheckpointError(f"{snapshot_path}: written for another body "
                                      f"({snapshot['description']}); remove it to start afresh")
            try:
                self.agent = NaiveAgent.from_state(self.body, snapshot["agent"])
                node = snapshot["node"]
                (self.last_passive, self.last_settled, self.n_povs, self.n_rows,
                 self.run_over) = (node["last_passive"], node["last_settled"], node["n_povs"],
                                   node["n_rows"], node["run_over"])
                self.body.requests, self.body.retransmits = node["requests"], node["retransmits"]
                self.body.round_trip_s = node["round_trip_s"]
                self.passive.extend(node["passive"])
            except (KeyError, TypeError, ValueError) as exc:
                raise CheckpointError(f"{snapshot_path}: incomplete agent snapshot "
                                      f"({type(exc).__name__}: {exc})") from exc
        journal_path = directory / JOURNAL_FILE
        # Records older than the snapshot: a kill fell between its replace and
        # the journal's truncation.
        passives = [p for p in journal.passives if p[1] > self.last_passive]
        self.passive.extend(passives)
        if passives:
            self.last_passive = passives[-1][1]
        self.body.replay = {n: a for n, a in journal.answers.items() if n > self.body.requests}
        self.published_before_restart = {k for k in journal.settled if k > self.last_settled}
        self.journal = AgentJournal(journal_path, journal.valid_bytes)
        self.body.journal = self.journal
        self.checkpoint_stats["replayed_passives"] = len(passives)
        if snapshot is not None or journal.valid_bytes:
            self._await_peers = True
            # The dead agent's last command (answer not journaled) may still be answered.
            self.predecessor_sent = max([self.body.requests, *self.body.replay]) + 1
            self.get_logger().warning(
                f"resuming: snapshot {'at change ' + str(self.last_settled) if snapshot else 'none'}"
                f", journal {len(passives)} passive sensations, {len(self.body.replay)} answers, "
                f"{len(self.published_before_restart)} published reactions"
                + (f", {journal.torn_bytes} torn bytes ignored" if journal.torn_bytes else ""))
            self._resume_timer = self.create_timer(float(self.graph["resend_period_s"]),
                                                   self.resend_idle_settle)

    def resend_idle_settle(self) -> None:
        """After a restart, while idle on a settled change, say so again until
        a new passive sensation arrives: the settle may have been published
        before the environment's subscription matched, or lost with the dead
        agent; so may the passive sensation that followed it."""
        if self.run_over:
            self._resume_timer.cancel()
        elif not self.passive and not self._stepping \
                and self.last_settled == self.last_passive >= 0:
            self.settled_pub.publish(UInt64(data=self.last_settled))
            self.settles_resent += 1

    def await_peers(self, timeout_s: float = 5.0) -> None:
        """Before the first publication after a restart (the journal replayed):
        give discovery time to match the body's and the environment's
        subscriptions (what a publisher sends before that is lost; re-sends
        would recover it, late)."""
        if not self._await_peers:
            return
        deadline = time.monotonic() + timeout_s
        while (self.command_pub.get_subscription_count() == 0
               or self.settled_pub.get_subscription_count() == 0) \
                and time.monotonic() < deadline and not self.body.aborted:
            self.spin_once(0.05)
        self._await_peers = False

    def take_snapshot(self) -> None:
        started = time.perf_counter()
        # The journal about to be emptied is what re-publishes, after a kill,
        # reactions that never left the process: wait until they were received
        # (readers acknowledge at the writer's heartbeat: dds_environment.HEARTBEAT_PERIOD_NS).
        for publisher in (self.pov_pub, self.compensation_pub, self.pov_record_pub,
                          self.compensation_record_pub, self.settled_pub):
            if not publisher.wait_for_all_acked(Duration(seconds=1.0)):
                self.checkpoint_stats["ack_timeouts"] += 1
        size = write_snapshot(self.journal.path.with_name(SNAPSHOT_FILE), {
            "config": self.cfg, "description": self.description, "agent": self.agent.state(),
            "node": {"last_passive": self.last_passive, "last_settled": self.last_settled,
                     "n_povs": self.n_povs, "n_rows": self.n_rows, "run_over": self.run_over,
                     "requests": self.body.requests, "retransmits": self.body.retransmits,
                     "round_trip_s": self.body.round_trip_s,
                     "passive": list(self.passive)}})
        self.journal.truncate()
        stats = self.checkpoint_stats
        stats["snapshots"] += 1
        stats["snapshot_bytes"] = size
        stats["last_snapshot_s"] = time.perf_counter() - started
        stats["snapshot_s"] += stats["last_snapshot_s"]
        self._last_snapshot = time.monotonic()

    def close(self) -> None:
        if self.journal is not None:
            self.journal.close()

    def log_retransmit(self, frame_id: str, waited_s: float) -> None:
        self.get_logger().warning(f"no answer to {frame_id} after {waited_s:.1f} s: sent again "
                                  f"({self.body.retransmits} re-sends so far)")

    # ------------------------------------------------------------ the run

    def abort(self) -> None:
        self.aborted = True
        if self.body is not None:
            self.body.aborted = True

    def on_sensation(self, msg) -> None:
        tracing.stamp("agent.answer")
        read = self.read_float_cloud("/body/sensation", msg,
                                     kinds=("cmd", "next", "change", "end"))
        if read is None:
            return
        (kind, number), cloud = read
        sensations = cloud.matrix
        if kind == "next":
            # A presend's answer; one nobody waits for is from an agent that
            # died, or came after the run's end.
            if not self.body.deliver(cloud.frame_id, sensations):
                self.late_answers += 1
            return
        if kind == "cmd":
            if self.body.deliver(cloud.frame_id, sensations):
                return
            if number < self.body.requests or number <= self.predecessor_sent \
                    or (number == self.body.requests and self.body.pending_number is None):
                # A second answer to a command already answered (a re-sent
                # copy), or the answer to a command of the agent that died.
                self.late_answers += 1
            else:
                self.drop("/body/sensation", f"{cloud.frame_id} answers no pending "
                          f"command (or has {len(sensations)} rows)")
            return
        if len(sensations) != 1:
            self.drop("/body/sensation", f"passive sensation with {len(sensations)} rows")
            return
        if number <= self.last_passive:
            # A re-sent change the agent already has. If it is the one last
            # settled, the settle may have been lost: say it again.
            if number == self.last_settled and not self.run_over:
                self.settled_pub.publish(UInt64(data=number))
                self.settles_resent += 1
            return
        self.last_passive = number
        tracing.stamp("agent.passive", number)
        if self._resume_timer is not None:     # in step with the environment again
            self._resume_timer.cancel()
            self._resume_timer = None
        if self.journal is not None:
            self.journal.passive(kind, number, sensations[0])
        self.passive.append((kind, number, sensations[0]))

    def step(self) -> None:
        """React to the queued passive sensations; call between callbacks, not inside one."""
        if self._stepping or self.run_over or self.agent is None or self.finished:
            return
        self._stepping = True
        try:
            while self.passive and not self.run_over:
                self.react(*self.passive.popleft())
        except RunAborted:
            pass
        except ExternalShutdownException:
            raise
        except Exception as exc:    # a bug in the agent: stop the node, name it, non-zero exit
            self.get_logger().error(f"naive agent failed: {type(exc).__name__}: {exc}")
            self.exit_code = 1
            self.finished = True
            raise
        finally:
            self._stepping = False

    def react(self, kind: str, number: int, sensation: np.ndarray) -> None:
        tracing.stamp("agent.react", number)
        header = messages.make_header(frame(kind, number), self.get_clock().now().nanoseconds)
        # Replayed after a restart and already settled by the agent that died.
        # Its reaction is published again all the same (the representation
        # ignores duplicates): what a killed process published last may
        # never have left it.
        published = number in self.published_before_restart
        self.await_peers()
        if kind == "end":
            self.run_over = True
            self.publish_stage_counters(header)
            self.done_pub.publish(messages.table_to_cloud(
                {"changes": number, "points_of_view": self.n_povs,
                 "compensation_rows": self.n_rows,
                 "compensated": self.agent.compensated,
                 "queries": self.agent.queries_total, "calls": self.agent.calls_total},
                self.columns["/agent/done"], header))
            self.settle(number, published)
            self.write_records()
            self.get_logger().info(
                f"run over: {self.n_povs} points of view, {self.n_rows} equality rows, "
                f"{self.body.requests} commands ({self.body.ahead_used} sent ahead with a "
                f"settle), {1e3 * self.body.round_trip_s / max(self.body.requests, 1):.3f} ms "
                "waited for each, "
                f"{self.body.retransmits} commands re-sent, {self.late_answers} late answers, "
                f"{self.body.replayed} answers and "
                f"{self.checkpoint_stats['replayed_passives']} passive sensations replayed, "
                f"{self.checkpoint_stats['snapshots']} snapshots "
                f"({self.checkpoint_stats['snapshot_s']:.2f} s, last "
                f"{self.checkpoint_stats['snapshot_bytes'] / 1e6:.1f} MB, "
                f"{self.checkpoint_stats['ack_timeouts']} acknowledgement waits timed out), "
                f"{self.general_reads.get('/body/sensation', 0)} sensations not read by the "
                "fast path")
            return
        if number == 0:
            reaction = self.agent.start(self.initial_motor_state)
        else:
            reaction = self.agent.react(sensation)
        self.publish_reaction(reaction, header)
        self.n_povs += len(reaction.new_pov_ids)
        self.n_rows += len(np.reshape(reaction.equality_rows, (-1, 3)))
        self.settle(number, published)

    def settle(self, number: int, published: bool) -> None:
        """Journal that change ``number``'s reaction is out, then settle it; a
        snapshot when one is due. The agent's last command (its rest, a
        ``BodyOverTopics.move``) is answered first: the arm is where it rests
        before the environment moves."""
        tracing.stamp("agent.await_rest", number)
        self.body.await_move()
        self.last_settled = number
        if not published:
            if self.journal is not None:
                self.journal.settled(number)
            tracing.stamp("agent.settle", number)
            self.settled_pub.publish(UInt64(data=number))
            tracing.stamp("agent.settled", number)
            if self.journal is not None and not self.passive and self.snapshot_due():
                self.take_snapshot()
        # After the snapshot (whose command count it is not part of), and for a
        # replayed change too (the dead agent sent it: the numbers stay in step).
        sweep = None if self.run_over else self.agent.next_sweep()
        if sweep is not None:
            self.body.presend(sweep, number + 1)
        tracing.stamp("agent.idle", number)

    def snapshot_due(self) -> bool:
        last_cost = self.checkpoint_stats["last_snapshot_s"]
        return time.monotonic() - self._last_snapshot >= max(
            self.snapshot_period_s, self.snapshot_cost_factor * last_cost)

    def publish_reaction(self, reaction, header) -> None:
        povs = np.asarray(reaction.new_povs, dtype=float)
        if len(povs):
            ids = np.asarray(reaction.new_pov_ids, dtype=np.int64)
            n_samples, n_motors = povs.shape[1:]
            self.pov_pub.publish(messages.table_to_cloud(
                {"pov": np.repeat(ids, n_samples), "sample": np.tile(np.arange(n_samples), len(ids)),
                 **{f"m{j}": povs[:, :, j].ravel() for j in range(n_motors)}},
                self.columns["/agent/points_of_view"], header))
            self.pov_record_pub.publish(messages.table_to_cloud(
                {"pov": ids, "event": np.asarray(self.agent.pov_events)[ids],
                 "queries": np.asarray(self.agent.pov_queries)[ids]},
                self.columns["/agent/pov_records"], header))
        if reaction.compensations:
            records = reaction.compensations
            motor = np.asarray([r.motor_state for r in records], dtype=float)
            anchor = np.asarray([r.anchor_motor_state for r in records], dtype=float)
            self.compensation_record_pub.publish(messages.table_to_cloud(
                {"event": [r.event for r in records],
                 "anchor_event": [r.anchor_event for r in records],
                 "pov": [r.pov for r in records], "searched": [r.searched for r in records],
                 **{f"m{j}": motor[:, j] for j in range(motor.shape[1])},
                 **{f"a{j}": anchor[:, j] for j in range(anchor.shape[1])}},
                self.columns["/agent/compensation_records"], header))
        rows = np.asarray(reaction.equality_rows, dtype=np.int64).reshape(-1, 3)
        if len(rows):
            self.compensation_pub.publish(messages.table_to_cloud(
                {"set": rows[:, 0], "pov_from": rows[:, 1], "pov_to": rows[:, 2]},
                self.columns["/agent/compensations"], header))

    def write_records(self) -> None:
        """``<graph.results_dir>/agent_records.npz``: the agent's own records
        (``NaiveAgentRecords``, what ``/agent/pov_records``,
        ``/agent/compensation_records`` and ``/agent/stage_counters`` carry), for
        an evaluation without a bag (``launch --no-record``)."""
        path = Path(self.graph["results_dir"]) / AGENT_RECORDS_FILE
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, **NaiveAgentRecords.from_agent(self.agent).to_arrays())

    def publish_stage_counters(self, header) -> None:
        """Motor states probed and round trips per stage (0 for a stage never entered)."""
        queries, calls = self.agent.queries_by_stage, self.agent.calls_by_stage
        counters = {"compensation_queries": int(sum(self.agent.compensation_queries))}
        for stage in NAIVE_STAGES:
            counters[f"queries_{stage}"] = queries.get(stage, 0)
            counters[f"calls_{stage}"] = calls.get(stage, 0)
        defaults = {name: getattr(NaiveAgentRecords, name) for name in STRUCTURE_FIELDS}
        counters.update({**defaults, **structure_fields(self.agent)})
        unknown = (set(queries) | set(calls)) - set(NAIVE_STAGES)
        if unknown:
            self.get_logger().error(f"stages {sorted(unknown)} have no /agent/stage_counters column")
        self.stage_counter_pub.publish(messages.table_to_cloud(
            counters, self.columns["/agent/stage_counters"], header))

    def publish_command(self, motor_states: np.ndarray, frame_id: str) -> None:
        self.await_peers()
        data = self.command_packer.pack(motor_states, frame_id, self.now_ns())
        traced = frame_id.startswith("cmd")       # not a presend (answered after a change)
        if traced:
            tracing.stamp("agent.publish")
        self.command_pub.publish(data)
        if traced:
            tracing.stamp("agent.published")


def main(args=None) -> int:
    return run_node(AgentNode, "agent", args)


if __name__ == "__main__":
    raise SystemExit(main())
