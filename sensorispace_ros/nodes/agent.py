"""Agent node: the naive agent (core.naive_agent.NaiveAgent, unchanged).

It subscribes to ``/body/sensation`` and nothing else, and meets its body
through ``BodyOverTopics``, whose ``sense(batch)`` publishes one
``/body/motor_command`` (frame ``cmd/<n>``) and spins the executor until the
sensation with that frame id arrives (SingleThreadedExecutor: measured
~0.2 ms round trips; MultiThreadedExecutor had 0.1-0.6 s outliers).

Passive sensations (``change/<k>``) are queued by the subscription callback;
``step()``, called by the spinning loop between callbacks (never inside
one), lets the agent react, publishes the new points of view and equality
rows, then ``/agent/settled`` = k. ``end/<k>`` ends the run:
``/agent/done`` carries the totals.

For the evaluator (recorded, read by ``sensorispace analyze``) it also
publishes its own bookkeeping, never anything of the world:
``/agent/pov_records`` (event and walk queries of each POV),
``/agent/compensation_records`` (each accepted compensation) and, at the
end, ``/agent/stage_counters``: together ``core.naive_evaluation.
NaiveAgentRecords``, the data the offline run is evaluated from.
"""
from __future__ import annotations

import collections
import time

import numpy as np
from rclpy.executors import ExternalShutdownException
from std_msgs.msg import UInt64

from .. import contracts, messages
from ..core.naive_agent import STAGES as NAIVE_STAGES
from ..core.naive_agent import NaiveAgent, NaiveParams
from . import GraphNode, frame, run_node


class RunAborted(RuntimeError):
    """The node is shutting down while the agent waits for its body."""


class BodyOverTopics:
    """A SensingBody whose ``sense`` is a round trip over the body's topics.

    ``spin_once(timeout_s)`` services the executor while the reply is
    awaited: the agent runs in the thread that spins, so the answer is
    handled without a thread hand-off (measured: a worker thread waiting on
    an Event cost 3-6 ms per round trip, GIL switching; see the report).
    """

    def __init__(self, publish_command, spin_once, n_motors: int, n_sensors: int):
        self._publish_command = publish_command
        self._spin_once = spin_once
        self.n_motors = n_motors
        self.n_sensors = n_sensors
        self._pending: tuple[str, int] | None = None
        self._reply: np.ndarray | None = None
        self.requests = 0
        self.aborted = False
        self.round_trip_s = 0.0          # total time spent waiting for the body

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        motor_states = np.asarray(motor_states, dtype=float)
        if motor_states.ndim != 2 or motor_states.shape[1] != self.n_motors:
            raise ValueError(f"motor_states must have shape (B, {self.n_motors}), "
                             f"got {motor_states.shape}")
        self.requests += 1
        frame_id = frame("cmd", self.requests)
        self._pending = (frame_id, len(motor_states))
        self._reply = None
        started = time.perf_counter()
        self._publish_command(motor_states, frame_id)
        while self._reply is None:
            if self.aborted:
                raise RunAborted("shutting down while waiting for the body")
            self._spin_once(0.5)
        self.round_trip_s += time.perf_counter() - started
        reply, self._reply = self._reply, None
        return reply

    def deliver(self, frame_id: str, sensations: np.ndarray) -> bool:
        """Hand a sensation to the waiting request; False if nobody waits for it."""
        if self._pending is None or self._pending[0] != frame_id:
            return False
        if len(sensations) != self._pending[1] or sensations.shape[1] != self.n_sensors:
            return False
        self._reply = sensations
        self._pending = None
        return True


class AgentNode(GraphNode):

    def __init__(self, **kwargs):
        super().__init__("agent", **kwargs)
        self.columns = {topic: contracts.contract(topic).columns for topic in (
            "/body/motor_command", "/body/sensation", "/agent/points_of_view",
            "/agent/compensations", "/agent/done", "/agent/pov_records",
            "/agent/compensation_records", "/agent/stage_counters")}
        self.command_pub = contracts.create_publisher(self, "/body/motor_command")
        self.pov_pub = contracts.create_publisher(self, "/agent/points_of_view")
        self.compensation_pub = contracts.create_publisher(self, "/agent/compensations")
        self.settled_pub = contracts.create_publisher(self, "/agent/settled")
        self.done_pub = contracts.create_publisher(self, "/agent/done")
        self.pov_record_pub = contracts.create_publisher(self, "/agent/pov_records")
        self.compensation_record_pub = contracts.create_publisher(
            self, "/agent/compensation_records")
        self.stage_counter_pub = contracts.create_publisher(self, "/agent/stage_counters")
        contracts.create_subscription(self, "/body/sensation", self.on_sensation)

        self.body = BodyOverTopics(self.publish_command, lambda t: self.spin_once(t),
                                   n_motors=len(self.columns["/body/motor_command"]),
                                   n_sensors=len(self.columns["/body/sensation"]))
        # The agent knows its own initial posture (proprioception), nothing of the world.
        self.initial_motor_state = np.asarray(self.cfg["arm"]["initial_motor_state"], float)
        self.agent = NaiveAgent(self.body, NaiveParams(**self.cfg["naive"]),
                                            self.cfg["seed"])
        self.passive: collections.deque = collections.deque()
        self.last_passive = -1
        self.n_povs = 0
        self.n_rows = 0
        self.run_over = False
        self.finished = False
        self.exit_code = 0
        self._stepping = False

    def abort(self) -> None:
        self.body.aborted = True

    def on_sensation(self, msg) -> None:
        decoded = self.decode("/body/sensation", msg, kinds=("cmd", "change", "end"))
        if decoded is None:
            return
        (kind, number), sensations = decoded
        if kind == "cmd":
            if not self.body.deliver(msg.header.frame_id, sensations):
                self.drop("/body/sensation", f"{msg.header.frame_id} answers no pending "
                          f"command (or has {len(sensations)} rows)")
            return
        if len(sensations) != 1:
            self.drop("/body/sensation", f"passive sensation with {len(sensations)} rows")
            return
        if number <= self.last_passive:
            return                      # a re-sent change the agent already has
        self.last_passive = number
        self.passive.append((kind, number, sensations[0]))

    def step(self) -> None:
        """React to the queued passive sensations; call between callbacks, not inside one."""
        if self._stepping or self.run_over:
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
        header = messages.make_header(frame(kind, number), self.get_clock().now().nanoseconds)
        if kind == "end":
            self.run_over = True
            self.publish_stage_counters(header)
            self.done_pub.publish(messages.table_to_cloud(
                {"changes": number, "points_of_view": self.n_povs,
                 "compensation_rows": self.n_rows,
                 "compensated": self.agent.compensated,
                 "queries": self.agent.queries_total, "calls": self.agent.calls_total},
                self.columns["/agent/done"], header))
            self.settled_pub.publish(UInt64(data=number))
            self.get_logger().info(
                f"run over: {self.n_povs} points of view, {self.n_rows} equality rows, "
                f"{self.body.requests} round trips "
                f"({1e3 * self.body.round_trip_s / max(self.body.requests, 1):.3f} ms each)")
            return
        if number == 0:
            reaction = self.agent.start(self.initial_motor_state)
        else:
            reaction = self.agent.react(sensation)
        self.publish_reaction(reaction, header)
        self.settled_pub.publish(UInt64(data=number))

    def publish_reaction(self, reaction, header) -> None:
        povs = np.asarray(reaction.new_povs, dtype=float)
        if len(povs):
            ids = np.asarray(reaction.new_pov_ids, dtype=np.int64)
            n_samples, n_motors = povs.shape[1:]
            self.pov_pub.publish(messages.table_to_cloud(
                {"pov": np.repeat(ids, n_samples), "sample": np.tile(np.arange(n_samples), len(ids)),
                 **{f"m{j}": povs[:, :, j].ravel() for j in range(n_motors)}},
                self.columns["/agent/points_of_view"], header))
            self.n_povs += len(povs)
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
            self.n_rows += len(rows)

    def publish_stage_counters(self, header) -> None:
        """Motor states probed and round trips per stage (0 for a stage never entered)."""
        queries, calls = self.agent.queries_by_stage, self.agent.calls_by_stage
        counters = {"compensation_queries": int(sum(self.agent.compensation_queries))}
        for stage in NAIVE_STAGES:
            counters[f"queries_{stage}"] = queries.get(stage, 0)
            counters[f"calls_{stage}"] = calls.get(stage, 0)
        unknown = (set(queries) | set(calls)) - set(NAIVE_STAGES)
        if unknown:
            self.get_logger().error(f"stages {sorted(unknown)} have no /agent/stage_counters column")
        self.stage_counter_pub.publish(messages.table_to_cloud(
            counters, self.columns["/agent/stage_counters"], header))

    def publish_command(self, motor_states: np.ndarray, frame_id: str) -> None:
        self.command_pub.publish(messages.matrix_to_cloud(
            motor_states, self.columns["/body/motor_command"],
            messages.make_header(frame_id, self.get_clock().now().nanoseconds)))


def main(args=None) -> int:
    return run_node(AgentNode, "agent", args)


if __name__ == "__main__":
    raise SystemExit(main())
