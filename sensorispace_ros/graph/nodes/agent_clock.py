"""The agent node in a world on its own clock (``world.clock: rows`` or ``wall``).

The configuration chooses the protocol, never when anything happens: with a
world that does not wait, no passive sensation announces a change and no
settle gates one, so the node runs the clocked agent
(``core.naive.clocked_agent.ClockedAgent``, driven as ``core.clocked_run``
drives it: ``graph.clocked_exploration``), which tells each change from its
own sensations. It starts once the body has described itself and listens
(its command, hold and sensation topics matched), holds still at rest with
one ``/body/hold`` message, and ends when the body answers a hold with
``end/<n>`` (its world has no change left) or when its simulation 2 has
taken ``naive.clock_equality_changes`` changes (it then sends ``end/<n>``).
What it found goes out at the end, all at once, under ``change/<k>`` (k the
reactions it kept), then ``/agent/done`` and the settle of ``end/<k>``: the
environment ends there. With ``graph.checkpoint_dir`` it resumes after a
kill -9 from its last snapshot, live (``graph.nodes.agent_restart``).
"""
from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np
from std_msgs.msg import UInt64

from sensorispace_ros import contracts, messages
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.graph import agent_outputs
from sensorispace_ros.graph.clocked_exploration import ClockOverTopics, explore_over_topics
from sensorispace_ros.graph.framework import frame
from sensorispace_ros.protocol import AGENT_RECORDS_FILE, run_directory
from sensorispace_ros.state.agent_journal import CheckpointError

PEERS_TIMEOUT_S = 30.0


class AgentClock:
    """What ``AgentNode`` does when ``world.clock`` is rows or wall."""

    def init_clock(self) -> None:
        self.clocked = self.cfg["world"]["clock"] != "agent"
        self.clock_view: ClockOverTopics | None = None
        self.clock_run = None          # the driver, kept for the evaluator (tests)
        self.clock_started = False
        self.clock_resumed = None      # (run, over) of a snapshot to go on with
        self.hold_pub = self.hold_packer = None
        # The frame ids of /body/sensation this protocol reads.
        self.sensation_kinds = ("cmd", "next", "change", "end") if not self.clocked else (
            "cmd", "hold", "end", "equality", "change")
        if not self.clocked:
            return
        self.hold_pub = contracts.create_publisher(self, "/body/hold")

    def start_clock(self) -> None:
        """Sized by the description: the hold's packer and the driver's view of the body."""
        self.hold_packer = messages.CloudCdrPacker(self.columns_of("/body/hold"))
        self.clock_view = ClockOverTopics(self.body)
        if self.checkpoint is None:
            return
        try:
            self.clock_resumed = self.resume_clock(self.clock_view)
        except CheckpointError as exc:
            self.get_logger().error(f"graph.checkpoint_dir: {exc}")
            self.exit_code = 2
            self.finished = True
            return

    def body_started_again(self) -> None:
        """A body restarted (its description came again): a hold it was
        watching is sent again (on the wall clock holds are not re-sent by time)."""
        if self.body is not None and self.body.hold_again():
            self.get_logger().warning(f"the body started again: hold/{self.body.requests} "
                                      "sent again")

    def publish_hold(self, motor_state: np.ndarray, low: np.ndarray, high: np.ndarray,
                     frame_id: str) -> None:
        row = np.concatenate([np.reshape(motor_state, -1), low, high])[None]
        self.note_sent()
        self.hold_pub.publish(self.hold_packer.pack(row, frame_id, self.now_ns()))

    def on_clock_sensation(self, kind: str, number: int, cloud) -> None:
        """A sensation in clocked mode: an answer, or the start of simulation 2."""
        if kind == "equality":
            self.clock_view.second_round = True
        elif kind in ("cmd", "hold", "end"):
            self.on_answer(kind, number, cloud)
        # change/<k> (a body that still announces its changes): not read

    def clock_peers_ready(self) -> bool:
        return (self.command_pub.get_subscription_count() > 0
                and self.hold_pub.get_subscription_count() > 0
                and self.count_publishers("/body/sensation") > 0)

    def run_clocked(self) -> None:
        """The whole exploration, then the results (the node's ``step``; once)."""
        if self.clock_started:
            return
        self.clock_started = True
        deadline = time.monotonic() + PEERS_TIMEOUT_S
        while not self.clock_peers_ready() and time.monotonic() < deadline:
            self.spin_once(0.05)
        naive = self.cfg["naive"]
        run, over = self.clock_resumed or (None, False)
        # A snapshot at the first reaction's end (the start it keeps is costly), then as due.
        self._last_snapshot = float("-inf")
        if not over:
            run = explore_over_topics(
                self.clock_view, self.initial_motor_state, self.cfg["seed"],
                NaiveParams(**naive), sweep_budget=naive["clock_sweep_budget"],
                equality_changes=naive["clock_equality_changes"],
                after_reaction=self.clock_boundary, run=run)
            if not self.clock_view.ended:
                self.body.end_run(run.agent.rest_motor_state)
        self.clock_run, self.agent = run, run.agent
        self.get_logger().info(agent_outputs.body_measure(run.agent))
        run.restarts, run.rows_lost_to_restart = self.clock_restarts, self.clock_rows_lost
        if self.clock_state is not None and not over:
            self.take_clock_snapshot(run, over=True)    # a kill now re-publishes the results
        self.end_clocked(len(run.event_states))

    def end_clocked(self, changes: int) -> None:
        """Publish what the agent found, its counters and totals; settle the end."""
        self.run_over = True
        agent = self.agent
        povs = agent.points_of_view
        pairs, set_ids = agent.equality_sets()
        everything = SimpleNamespace(
            new_povs=povs, new_pov_ids=np.arange(len(povs)), compensations=agent.compensations,
            equality_rows=np.column_stack([set_ids, np.reshape(pairs, (-1, 2))]))
        header = messages.make_header(frame("change", changes - 1), self.now_ns())
        for topic, table in agent_outputs.reaction_tables(agent, everything).items():
            self.publish_table(topic, table, header)
        self.n_povs = len(povs)
        self.n_rows = len(everything.equality_rows)
        header = messages.make_header(frame("end", changes), self.now_ns())
        counters, _ = agent_outputs.stage_counters(agent)
        self.publish_table("/agent/stage_counters", counters, header)
        self.publish_table("/agent/done", agent_outputs.done_totals(
            agent, changes, self.n_povs, self.n_rows), header)
        self.last_settled = changes
        self.settled_pub.publish(UInt64(data=changes))
        path = run_directory(self.graph["results_dir"], messages.stamp_ns(header))
        agent_outputs.write_records(agent, path / AGENT_RECORDS_FILE)
        found = agent_outputs.account(agent, self.n_povs, self.n_rows, changes - 1)
        self.get_logger().info(f"run over: {found}; {self.clock_line()}; records written to "
                               f"{path / AGENT_RECORDS_FILE}")
        self.finish_when_done()

    def clock_line(self) -> str:
        """What the clock cost the agent, in its own counts."""
        run = self.clock_run
        return (f"{len(run.event_states) - 1} reactions kept, {run.undone} undone "
                f"({run.lost_rows} motor states lost, {run.salvaged} POVs salvaged), "
                f"{sum(run.log.flagged)} changes flagged in {len(run.log.flagged)} tests, "
                f"{run.restarts} restarts ({run.rows_lost_to_restart} rows lost to them), "
                f"{self.checkpoint_stats['snapshots']} snapshots "
                f"({self.checkpoint_stats['snapshot_s']:.3f} s, last "
                f"{self.checkpoint_stats['snapshot_bytes']} bytes)")
