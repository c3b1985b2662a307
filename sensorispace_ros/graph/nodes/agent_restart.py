"""The agent node's resumption after a kill -9 (``graph.checkpoint_dir``).

The checkpoint is read and checked at start-up (a bad one stops the node
there), and resumed once the body description has come. The node persists
``<dir>/agent.snapshot`` and ``<dir>/agent.journal`` (format and fields:
``state.agent_journal``). The journal gets, unbuffered, every input the
agent consumes: each new passive sensation when it arrives, each body
answer (with a crc of the command it answers), and a marker once a change's
reaction is published. At an event boundary, at most every
``snapshot_period_s`` of wall time and every ``snapshot_cost_factor`` times
the last snapshot's duration, the snapshot is replaced atomically and the
journal emptied. A restarted agent loads the snapshot, re-feeds the journal
through the deterministic NaiveAgent (answers come from the journal, checked
by command number and crc) and publishes the replayed reactions again (what
a killed process published last may never have left it; the representation
ignores duplicates, the analysis takes the first copy; the snapshot waits
until its publishers' messages are acknowledged before it empties the
journal), settling only changes without a marker; where the journal ends
mid-change, it continues live: its next command carries the same
``cmd/<n>`` as the one the dead agent sent (the body answers duplicates
identically). Before its first publication it waits (<= 5 s) until the
body's and the environment's subscriptions have matched. Until the first
new passive sensation arrives, whenever it is idle on a settled change it
re-publishes that settle every ``graph.resend_period_s``. The snapshot is a
pickle: the checkpoint directory must be as trusted as the code.

In a world on its own clock (``world.clock`` rows or wall) the world does
not wait for a dead agent: nothing is replayed and there is no journal. At
a reaction's end (the agent idle, ``graph.clocked_exploration``): the first,
then as often as above, the snapshot is the whole driver
(``core.clocked_run.ClockedRun``: the agent, its tests, its loop); once more
when the run is over. Before
every command or hold the node writes ``<dir>/agent.clock``
(``state.resting_state``, one ``os.pwrite``): the command's number, the rows
its commands sent so far and the restarts. A restarted agent loads the
snapshot and goes on live from it: its commands number on after the dead
agent's last (the body answers a number sent again with its first answer),
and the rows sent between the snapshot and the death are lost work
(``rows_lost_to_restart``; the world kept its clock meanwhile, and the agent
holds at rest as after any reaction and tells a change as ever). A snapshot
of a run over re-publishes its results.
"""
from __future__ import annotations

import time
from pathlib import Path

from rclpy.duration import Duration
from std_msgs.msg import UInt64

from sensorispace_ros.core.clocked_run import ClockedRun
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.state.agent_journal import (JOURNAL_FILE, SNAPSHOT_FILE, AgentJournal,
    CheckpointError, node_snapshot, read_journal, read_snapshot, restore_node,
    write_snapshot)
from sensorispace_ros.state.resting_state import RestingStateFile

# A world on its own clock: the last command's number, the rows sent, the restarts.
CLOCK_STATE_FILE = "agent.clock"


# What a reaction publishes (``graph.agent_outputs.reaction_tables``).
REACTION_TOPICS = ("/agent/points_of_view", "/agent/compensations", "/agent/pov_records",
                   "/agent/compensation_records")


class AgentRestart:
    """What ``AgentNode`` does to resume after a kill -9 (see the module docstring)."""

    # Snapshots take <= 1 % of the run (their cost: docs/benchmarks.md).
    snapshot_period_s = 5.0
    snapshot_cost_factor = 100.0

    def init_restart(self) -> None:
        self.journal: AgentJournal | None = None
        self.published_before_restart: set[int] = set()
        self.checkpoint_stats = {"snapshots": 0, "snapshot_bytes": 0, "snapshot_s": 0.0,
                                 "last_snapshot_s": 0.0, "replayed_passives": 0,
                                 "ack_timeouts": 0}
        self._last_snapshot = time.monotonic()
        self._resume_timer = None
        self._await_peers = False
        self.checkpoint = None
        self.clock_state: RestingStateFile | None = None
        self.clock_restarts = self.clock_rows_lost = 0

    def read_checkpoint(self, directory: Path) -> tuple:
        """The snapshot and the journal of ``directory`` (none: a fresh start),
        read and checked against this run's configuration."""
        snapshot_path = directory / SNAPSHOT_FILE
        snapshot = read_snapshot(snapshot_path)
        if snapshot is not None and snapshot.get("config") != self.cfg:
            raise CheckpointError(f"{snapshot_path}: written by a run with another "
                                  "configuration; remove it to start afresh")
        if self.clocked:
            if snapshot is not None and not isinstance(snapshot.get("run"), ClockedRun):
                raise CheckpointError(f"{snapshot_path}: no clocked run in the agent snapshot")
            self.clock_state = RestingStateFile(directory / CLOCK_STATE_FILE, 3)
            return directory, snapshot, None
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
                restore_node(snapshot["node"], self, self.body)
            except (KeyError, TypeError, ValueError) as exc:
                raise CheckpointError(f"{snapshot_path}: incomplete agent snapshot "
                                      f"({type(exc).__name__}: {exc})") from exc
        # Records older than the snapshot: a kill fell between its replace and
        # the journal's truncation.
        passives = [p for p in journal.passives if p[1] > self.last_passive]
        self.passive.extend(passives)
        if passives:
            self.last_passive = passives[-1][1]
        self.body.replay = {n: a for n, a in journal.answers.items() if n > self.body.requests}
        self.published_before_restart = {k for k in journal.settled if k > self.last_settled}
        self.journal = AgentJournal(directory / JOURNAL_FILE, journal.valid_bytes)
        self.body.journal = self.journal
        self.checkpoint_stats["replayed_passives"] = len(passives)
        if snapshot is not None or journal.valid_bytes:
            self.resume_live(snapshot is not None, len(passives), journal.torn_bytes)

    def resume_live(self, from_snapshot: bool, n_passives: int, torn_bytes: int) -> None:
        self._await_peers = True
        # The dead agent's last command (answer not journaled) may still be answered.
        self.predecessor_sent = max([self.body.requests, *self.body.replay]) + 1
        self.get_logger().warning(
            f"resuming: snapshot {'at change ' + str(self.last_settled) if from_snapshot else 'none'}"
            f", journal {n_passives} passive sensations, {len(self.body.replay)} answers, "
            f"{len(self.published_before_restart)} published reactions"
            + (f", {torn_bytes} torn bytes ignored" if torn_bytes else ""))
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

    def caught_up(self) -> None:
        """A new passive sensation came: in step with the environment again."""
        if self._resume_timer is not None:
            self._resume_timer.cancel()
            self._resume_timer = None

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
        for publisher in (*(self.pubs[topic] for topic in REACTION_TOPICS), self.settled_pub):
            if not publisher.wait_for_all_acked(Duration(seconds=1.0)):
                self.checkpoint_stats["ack_timeouts"] += 1
        size = write_snapshot(self.journal.path.with_name(SNAPSHOT_FILE), {
            "config": self.cfg, "description": self.description, "agent": self.agent.state(),
            "node": node_snapshot(self, self.body)})
        self.journal.truncate()
        self.snapshot_taken(started, size)

    def snapshot_taken(self, started: float, size: int) -> None:
        """Count a snapshot of ``size`` bytes begun at ``started`` (perf_counter)."""
        stats = self.checkpoint_stats
        stats["snapshots"] += 1
        stats["snapshot_bytes"] = size
        stats["last_snapshot_s"] = time.perf_counter() - started
        stats["snapshot_s"] += stats["last_snapshot_s"]
        self._last_snapshot = time.monotonic()

    def snapshot_due(self) -> bool:
        last_cost = self.checkpoint_stats["last_snapshot_s"]
        return time.monotonic() - self._last_snapshot >= max(
            self.snapshot_period_s, self.snapshot_cost_factor * last_cost)

    def close(self) -> None:
        if self.journal is not None:
            self.journal.close()

    # ------------------------------------------------ a world on its own clock

    def resume_clock(self, view):
        """Before the run (the body described): the run to go on with, if the
        checkpoint holds one (its view bound to this node's body), else None;
        the commands number on after the dead agent's last."""
        directory, snapshot, _ = self.checkpoint
        self.checkpoint = None
        saved = self.clock_state.load()
        if snapshot is None and saved is None:
            return None                 # a fresh start
        run, requests, rows = None, 0, 0
        if snapshot is not None:
            run = snapshot["run"]
            try:
                run.body.bind(self.body)
                requests = int(snapshot["requests"])
            except (AttributeError, KeyError, TypeError, ValueError) as exc:
                raise CheckpointError(f"{directory / SNAPSHOT_FILE}: unusable clocked run "
                                      f"({type(exc).__name__}: {exc})") from exc
            view, rows = run.body, run.body.rows_sent
            self.clock_restarts, self.clock_rows_lost = run.restarts, run.rows_lost_to_restart
        if saved is not None:
            sent, sent_rows, restarts = (int(x) for x in saved)
            requests = max(requests, sent)
            self.clock_rows_lost += max(sent_rows - rows, 0)
            self.clock_restarts = max(self.clock_restarts, restarts)
            view.rows_sent = max(rows, sent_rows)
        self.clock_restarts += 1
        self.clock_view = view
        # The dead agent's last commands: a late answer to one is dropped quietly.
        self.body.requests = self.predecessor_sent = requests
        self.note_sent()
        over = snapshot is not None and bool(snapshot.get("over"))
        self.get_logger().warning(
            f"resuming on the clock (restart {self.clock_restarts}): "
            + (f"snapshot of {len(run.event_states) - 1} reactions kept, "
               f"{len(run.agent.points_of_view)} POVs{', the run over' if over else ''}"
               if run is not None else "no snapshot, a fresh start")
            + f"; commands from {requests + 1}, {self.clock_rows_lost} rows lost to restarts")
        return run, over

    def note_sent(self) -> None:
        """Before a command or hold goes out: its number, the rows sent, the restarts."""
        if self.clock_state is not None:
            self.clock_state.save((self.body.requests, self.clock_view.rows_sent,
                                   self.clock_restarts))

    def clock_boundary(self, run) -> None:
        """A reaction's end (the agent idle): a snapshot when one is due."""
        if self.clock_state is not None and self.snapshot_due():
            self.take_clock_snapshot(run)

    def take_clock_snapshot(self, run, over: bool = False) -> None:
        started = time.perf_counter()
        run.restarts, run.rows_lost_to_restart = self.clock_restarts, self.clock_rows_lost
        size = write_snapshot(self.clock_state.path.with_name(SNAPSHOT_FILE), {
            "config": self.cfg, "description": self.description, "run": run,
            "requests": self.body.requests, "over": over})
        self.snapshot_taken(started, size)
