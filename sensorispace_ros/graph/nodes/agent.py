"""Agent node: the naive agent (core.naive.agent.NaiveAgent, unchanged); in a
world on its own clock the clocked agent (``graph.nodes.agent_clock``).

It subscribes to ``/body/sensation`` and ``/body/description`` only, and
starts once the body has said what it is (the latched description): the
naive agent, its commands and its sensations are sized from that, never
from the configuration; sensations that come before it wait. It meets its
body through ``graph.body_over_topics.BodyOverTopics`` (a ``sense`` is a
round trip of ``/body/motor_command`` and ``/body/sensation``, spun in this
thread; each settle sends the next change's first call ahead), as
serialized bytes (``messages.CloudCdrPacker``).

Passive sensations (``change/<k>``) are queued by the subscription callback;
``step()``, called by the spinning loop between callbacks (never inside
one), lets the agent react, publishes the new points of view and equality
rows, then ``/agent/settled`` = k. ``end/<k>`` ends the run: the equality
sets the agent's lattice implies, then ``/agent/done`` with the totals.

For the evaluator (recorded, read by ``sensorispace analyze``) it also
publishes its own bookkeeping, never anything of the world:
``/agent/pov_records`` (event and walk queries of each POV),
``/agent/compensation_records`` (each accepted compensation) and, at the
end, ``/agent/stage_counters``: together ``core.naive.records.
NaiveAgentRecords``, also written to ``<run directory>/agent_records.npz``
(``protocol.run_directory``) for a run evaluated without a bag.

It logs what it measured of its body (pose rank, POV dimension, the start it
chose for a degenerate one: ``core.naive.start``) and, at the end, what it
found (``graph.agent_outputs``); then it exits unless ``graph.exit_when_done``
is false. Restart after a kill -9: ``graph.nodes.agent_restart``.

Retransmit: a command unanswered after ``graph.command_timeout_s`` is re-sent
(``BodyOverTopics``); a late duplicate answer is dropped. A passive of the change
last settled settles it again (a restarted environment lost the settle).
"""
from __future__ import annotations

import collections
from pathlib import Path

import numpy as np
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from std_msgs.msg import UInt64

from sensorispace_ros import config, contracts, messages
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.graph import agent_outputs, tracing
from sensorispace_ros.graph.body_over_topics import BodyOverTopics, RunAborted
from sensorispace_ros.graph.framework import GraphNode, frame, run_node
from sensorispace_ros.graph.nodes.agent_clock import AgentClock
from sensorispace_ros.graph.nodes.agent_restart import AgentRestart
from sensorispace_ros.protocol import AGENT_RECORDS_FILE, run_directory
from sensorispace_ros.state.agent_journal import CheckpointError

TOPICS = ("/body/motor_command", "/body/sensation", "/agent/points_of_view",
          "/agent/compensations", "/agent/done", "/agent/pov_records",
          "/agent/compensation_records", "/agent/stage_counters")


class AgentNode(AgentRestart, AgentClock, GraphNode):

    def __init__(self, **kwargs):
        super().__init__("agent", **kwargs)
        self.columns: dict[str, dict] = {}   # by topic, sized by the body description
        self.command_pub = contracts.create_publisher(self, "/body/motor_command")
        # Commands go out and answers come in as serialized bytes (messages.CloudCdrPacker,
        # GraphNode.read_float_cloud): rclpy's message conversions would cost more
        # than the rest of a round trip, once per sense call each way.
        self.command_packer: messages.CloudCdrPacker | None = None
        self.pubs = {topic: contracts.create_publisher(self, topic) for topic in TOPICS[2:]}
        self.settled_pub = contracts.create_publisher(self, "/agent/settled")
        contracts.create_subscription(
            self, "/body/sensation", self.when_described("/body/sensation", self.on_sensation),
            raw=True)
        # Sized by the body description (start_body).
        self.body: BodyOverTopics | None = None
        self.agent: NaiveAgent | None = None
        self.initial_motor_state: np.ndarray | None = None
        self.aborted = False
        self.passive: collections.deque = collections.deque()
        self.last_passive = self.last_settled = -1
        self.settles_resent = self.late_answers = self.predecessor_sent = 0
        self.n_povs = self.n_rows = 0
        self.run_over = self.finished = self._stepping = False
        self.exit_code = 0
        self.init_restart()
        self.init_clock()
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
                                   on_retransmit=lambda frame_id, waited_s: self.get_logger()
                                   .warning(f"no answer to {frame_id} after {waited_s:.1f} s: "
                                            f"sent again ({self.body.retransmits} so far)"),
                                   description=description,
                                   publish_hold=self.publish_hold, resend_holds=self.clock == "rows")
        self.body.aborted = self.aborted
        self.initial_motor_state, said = agent_outputs.initial_posture(
            self.cfg["arm"]["initial_motor_state"], description.n_motors)
        if said:
            self.get_logger().info(said)
        if self.clocked:            # the agent is made by its driver (graph.nodes.agent_clock)
            return self.start_clock()
        self.agent = NaiveAgent(self.body, NaiveParams(**self.cfg["naive"]))
        if self.checkpoint is not None:
            checkpoint, self.checkpoint = self.checkpoint, None
            try:
                self.restore(*checkpoint)
            except CheckpointError as exc:
                self.get_logger().error(f"graph.checkpoint_dir: {exc}")
                self.exit_code = 2
                self.finished = True

    # ------------------------------------------------------------ the run

    def abort(self) -> None:
        self.aborted = True
        if self.body is not None:
            self.body.aborted = True

    def on_sensation(self, msg) -> None:
        tracing.stamp("agent.answer")
        read = self.read_float_cloud("/body/sensation", msg, kinds=self.sensation_kinds)
        if read is None:
            return
        (kind, number), cloud = read
        if self.clocked:
            return self.on_clock_sensation(kind, number, cloud)
        if kind in ("cmd", "next"):
            self.on_answer(kind, number, cloud)
            return
        sensations = cloud.matrix
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
        self.caught_up()
        if self.journal is not None:
            self.journal.passive(kind, number, sensations[0])
        self.passive.append((kind, number, sensations[0]))

    def on_answer(self, kind: str, number: int, cloud) -> None:
        """An answer to a command: to the one waited for, or late."""
        if self.body.deliver(cloud.frame_id, cloud.matrix):
            return
        # A presend's answer nobody waits for is from an agent that died, or
        # came after the run's end; a second answer to a command already
        # answered (a re-sent copy), or to a command of the agent that died.
        if kind == "next" or number < self.body.requests or number <= self.predecessor_sent \
                or (number == self.body.requests and self.body.pending_number is None):
            self.late_answers += 1
        else:
            self.drop("/body/sensation", f"{cloud.frame_id} answers no pending "
                      f"command (or has {len(cloud.matrix)} rows)")

    def step(self) -> None:
        """React to the queued passive sensations; call between callbacks, not inside one."""
        if self._stepping or self.run_over or self.finished or (
                self.agent is None and self.clock_view is None):
            return
        self._stepping = True
        try:
            if self.clocked:
                self.run_clocked()
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
            self.end_run(number, header, published)
            return
        if number == 0:
            reaction = self.agent.start(self.initial_motor_state, seed=self.cfg["seed"])
            self.get_logger().info(agent_outputs.body_measure(self.agent))
        else:
            reaction = self.agent.react(sensation)
        for topic, table in agent_outputs.reaction_tables(self.agent, reaction).items():
            self.publish_table(topic, table, header)
        self.n_povs += len(reaction.new_pov_ids)
        self.n_rows += len(np.reshape(reaction.equality_rows, (-1, 3)))
        self.settle(number, published)

    def end_run(self, number: int, header, published: bool) -> None:
        """The run is over: the counters and totals, the settle of the end, the
        records written, what the agent found said; the node exits unless
        ``graph.exit_when_done`` is false."""
        self.run_over = True
        self.n_rows += agent_outputs.publish_end_of_run(self.agent, self.publish_table, header)
        counters, unknown = agent_outputs.stage_counters(self.agent)
        if unknown:
            self.get_logger().error(f"stages {unknown} have no /agent/stage_counters column")
        self.publish_table("/agent/stage_counters", counters, header)
        self.publish_table("/agent/done", agent_outputs.done_totals(
            self.agent, number, self.n_povs, self.n_rows), header)
        self.settle(number, published)
        path = run_directory(self.graph["results_dir"], messages.stamp_ns(header))
        agent_outputs.write_records(self.agent, path / AGENT_RECORDS_FILE)
        self.get_logger().info(agent_outputs.transport(
            self.body, self.late_answers, self.checkpoint_stats,
            self.general_reads.get("/body/sensation", 0)))
        found = agent_outputs.account(self.agent, self.n_povs, self.n_rows, number - 1)
        self.get_logger().info(f"run over: {found}; records written to "
                               f"{path / AGENT_RECORDS_FILE}")
        self.finish_when_done()

    def finish_when_done(self) -> None:
        """With ``graph.exit_when_done``: end once every subscriber has the
        agent's last messages (or 2 s passed)."""
        if self.graph["exit_when_done"]:
            for publisher in (*self.pubs.values(), self.settled_pub):
                publisher.wait_for_all_acked(Duration(seconds=2.0))
            self.finished = True

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

    def publish_table(self, topic: str, table: dict, header) -> None:
        self.pubs[topic].publish(messages.table_to_cloud(table, self.columns[topic], header))

    def publish_command(self, motor_states: np.ndarray, frame_id: str) -> None:
        self.await_peers()
        data = self.command_packer.pack(motor_states, frame_id, self.now_ns())
        traced = frame_id.startswith("cmd")       # not a presend (answered after a change)
        self.note_sent()                          # a world on its own clock: agent_restart
        if traced:
            tracing.stamp("agent.publish")
        self.command_pub.publish(data)
        if traced:
            tracing.stamp("agent.published")


def main(args=None) -> int:
    return run_node(AgentNode, "agent", args)


if __name__ == "__main__":
    raise SystemExit(main())
