"""Environment node: plays the world's schedule of object changes.

Publishes the hidden lights (``/environment/lights``, frame ``change/<k>``)
and the ground truth of each change (``/environment/event``); waits for the
agent's ``/agent/settled`` = k before the next change (the paper's static
environment during compensation). The end of the run is one more lights
message, ``end/<k>``, with unchanged lights: the body turns it into a passive
sensation, so the agent learns of the end only through its body.

Restart: with ``graph.checkpoint_dir`` set, ``{current, settled}`` is written to
``<dir>/environment.json`` (``state.environment_record``; the launcher polls it
for its progress line) at every change, at the end and when the run is complete:
a fixed-size JSON record overwritten in place by one ``os.pwrite`` (a kill
cannot tear a one-page write; cheaper than a renamed file, docs/benchmarks.md).
A restarted environment does not rewind: it resumes at ``current`` (re-publishes
its event and lights; the world and its schedule are rebuilt from the seed), or
goes on to the next change if ``current`` was already settled, and re-sends the
current lights every ``graph.resend_period_s`` until the agent settles it (a
settle sent while the environment was dead is lost; the agent answers a re-sent
change it already settled with its settle again). A repeated settle of the
change before ``current`` (a restarted agent that lost the passive sensation of
``current``) is answered with the current lights again. Bag and analysis see the
re-sent messages as duplicates (first occurrence wins).

In a world on its own clock nothing waits for the agent: with
``world.clock: wall`` the changes come on a ROS timer, seeded exponential
gaps of mean ``world.change_period_s`` (stream ``world.clock``), the
schedule played twice when the agent has an equality pass
(``core.world_clock.clock_events``), then ``end/<k>``; with ``rows``
the body keeps the clock and this node publishes no lights. Either way the
agent's settle (of its end) ends the run. A restarted environment on the
wall clock publishes ``current`` again (the body ignores lights it has) and
goes on with the gaps the seed draws after it: what the world would have
done while the node was dead is not played.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from sensorispace_ros import contracts, messages
from sensorispace_ros.graph import tracing
from sensorispace_ros.state.environment_record import (PROGRESS_FILE, ProgressWriter,
    decode_progress)
from sensorispace_ros.core.seeding import rng_for
from sensorispace_ros.core.world_clock import CLOCK_STREAM, clock_events
from sensorispace_ros.graph.framework import GraphNode, build_world, frame, run_node
from sensorispace_ros.protocol import KIND_CODES

# One participant announcement period of the graph's Fast DDS profile
# (dds_environment.LEASE_ANNOUNCEMENT_S = 1 s) plus a margin; see _peers_ready.
RECORDER_DISCOVERY_S = 1.5
PEER_POLL_S = 0.02


class EnvironmentNode(GraphNode):

    def __init__(self, **kwargs):
        super().__init__("environment", **kwargs)
        self.world = build_world(self.cfg)
        self.events = (list(self.world.events) if self.clock == "agent"
                       else clock_events(self.world, self.cfg))
        self.n_changes = len(self.events)
        self.wall_timer = None
        self.wall_gaps = rng_for(self.cfg["seed"], CLOCK_STREAM)
        self.wall_period_s = float(self.cfg["world"]["change_period_s"])
        self.lights_pub = contracts.create_publisher(self, "/environment/lights")
        # Published as serialized bytes (the body takes them raw): the
        # hand-over of every change waits for them.
        self.lights_packer = messages.CloudCdrPacker(
            contracts.contract("/environment/lights").columns)
        self.event_pub = contracts.create_publisher(self, "/environment/event")
        contracts.create_subscription(self, "/agent/settled", self.on_settled)
        self.current, self.settled = -1, -1   # the last change published (end: n + 1), settled
        self.lights = self.world.initial_lights
        self.finished = self.run_complete = False
        self.progress_file = (Path(self.graph["checkpoint_dir"]) / PROGRESS_FILE
                              if self.graph["checkpoint_dir"] else None)
        self.progress_writer = (ProgressWriter(self.progress_file)
                                if self.progress_file is not None else None)
        self._graph_seen_at: float | None = None
        self.resuming = self._load_progress()
        # after a restart: the change whose lights are re-sent until it is settled
        self.resent_until_settled = self.current if self.resuming else None
        # Until the agent settles on the initial layout its subscription may
        # not be matched yet; volatile messages sent before are lost, so the
        # start is re-sent (the agent ignores duplicates).
        self.timer = self.create_timer(float(self.graph["resend_period_s"]), self.on_timer)
        # The graph is usually complete a few hundred ms after the nodes' start-up:
        # look for it every PEER_POLL_S, not only every resend period.
        self.start_timer = self.create_timer(PEER_POLL_S, self.on_start_timer)
        self.get_logger().info(f"{self.n_changes} environmental changes scheduled")

    def _load_progress(self) -> bool:
        """``current`` and ``settled`` of a killed predecessor; True if there were any."""
        if self.progress_file is None or not self.progress_file.is_file():
            return False
        try:
            current, settled = decode_progress(self.progress_file.read_bytes())
        except (OSError, ValueError) as exc:
            self.get_logger().error(f"{self.progress_file}: unreadable ({exc}); starting afresh")
            return False
        if not (0 <= current <= self.n_changes + 1 and -1 <= settled <= current):
            self.get_logger().error(f"{self.progress_file}: current {current}, settled "
                                    f"{settled} do not fit {self.n_changes} changes; "
                                    "starting afresh")
            return False
        self.current, self.settled = current, settled
        self.lights = self._lights_of(current)
        self.get_logger().warning(f"restarted: resuming at change {current} "
                                  f"(settled {settled}) from {self.progress_file}")
        return True

    def _lights_of(self, k: int) -> np.ndarray:
        """The layout after change k (the end, n + 1, keeps change n's)."""
        k = min(k, self.n_changes)
        return self.world.initial_lights if k == 0 else self.events[k - 1].lights

    def _save_progress(self) -> None:
        if self.progress_writer is not None:
            self.progress_writer.write(self.current, self.settled)

    def close(self) -> None:
        if self.progress_writer is not None:
            self.progress_writer.close()

    def _peers_ready(self) -> bool:
        present = set(self.get_node_names())
        missing = [n for n in self.graph["wait_for_nodes"] if n not in present]
        if missing:
            self.get_logger().info(f"waiting for {', '.join(missing)}", throttle_duration_sec=5.0)
            return False
        if "recorder" not in self.graph["wait_for_nodes"]:
            return True
        # /environment/event is volatile: a restarted environment would lose the
        # re-sent event if it published before the recorder's reader matched.
        if self.event_pub.get_subscription_count() == 0:
            return False
        # The other nodes' volatile writers (the agent's /agent/settled, ...) match
        # the recorder's readers when their participants have discovered each other,
        # which can take until the next participant announcement (measured: the
        # first 25 settles, ~1 s, missing from the bag). Everyone has announced
        # itself once RECORDER_DISCOVERY_S after this node saw the whole graph.
        now = time.monotonic()
        if self._graph_seen_at is None:
            self._graph_seen_at = now
        return now - self._graph_seen_at >= RECORDER_DISCOVERY_S

    def resume(self) -> None:
        """Carry on where the killed environment stopped (never rewinds)."""
        self.resuming = False
        k = self.current
        if self.settled < k:
            if k <= self.n_changes:
                self.publish_change(k)
            else:
                self.publish_lights(frame("end", k))
        else:                      # killed between the settle and the next change
            self.settled = k - 1
            self.on_settled_number(k)

    def on_start_timer(self) -> None:
        if self.current >= 0 or self.resuming:
            self.start_timer.cancel()
        elif self._peers_ready():
            self.start_timer.cancel()
            if self.clock == "rows":
                self.current = 0
                self.get_logger().info("world.clock rows: the body keeps the clock")
                return
            self.publish_change(0)
            if self.clock == "wall":
                self.next_wall_change()

    def resume_on_clock(self) -> None:
        """Wall clock: ``current``'s lights again, then the gap the seed draws
        after it (the gaps before it are drawn and set aside)."""
        self.resuming = False
        if self.clock != "wall":
            return
        if self.current > self.n_changes:
            self.publish_current_lights()
            return
        self.wall_gaps.exponential(self.wall_period_s, size=self.current)
        self.publish_change(self.current)
        self.next_wall_change()

    def next_wall_change(self) -> None:
        """wall: the next change after a seeded exponential gap, whatever the agent does."""
        gap_s = self.wall_gaps.exponential(self.wall_period_s)
        self.wall_timer = self.create_timer(gap_s, self.on_wall_timer)

    def on_wall_timer(self) -> None:
        self.destroy_timer(self.wall_timer)
        self.wall_timer = None
        if self.run_complete:
            return
        k = self.current + 1
        if k <= self.n_changes:
            self.publish_change(k)
            self.next_wall_change()
        else:
            self.current = k
            self._save_progress()
            self.publish_lights(frame("end", k))
            self.get_logger().info(f"world.clock wall: {self.n_changes} changes played")

    def on_timer(self) -> None:
        if self.resuming:
            if self._peers_ready():
                (self.resume if self.clock == "agent" else self.resume_on_clock)()
            return
        if self.clock != "agent":
            return
        if self.resent_until_settled is not None:
            if self.settled >= self.resent_until_settled:
                self.resent_until_settled = None
            else:
                self.publish_current_lights()
            return
        if self.current < 0:
            return                  # not started: on_start_timer's job
        if self.settled < 0:
            self.publish_lights(frame("change", 0))

    def on_settled(self, msg) -> None:
        k = int(msg.data)
        tracing.stamp("environment.settled", k)
        if self.clock != "agent":       # the agent's end: the run is over
            self.run_complete = True
            self.timer.cancel()
            self.get_logger().info(f"run complete: the agent ended after {k - 1} reactions")
            self.finished = bool(self.graph["exit_when_done"])
            return
        if k == self.settled == self.current - 1 and not self.resuming:
            # A restarted agent that lost the passive sensation of `current` re-sends
            # its last settle: the current lights again make the body send it again
            # (the agent ignores passives it already has).
            self.publish_current_lights()
            return
        if k != self.current or k <= self.settled:
            self.drop("/agent/settled", f"settled {k} while waiting for {self.current}")
            return
        self.on_settled_number(k)

    def on_settled_number(self, k: int) -> None:
        self.resuming = False
        self.settled = k
        if k < self.n_changes:
            self.publish_change(k + 1)              # saves {k + 1, k}
        elif k == self.n_changes:
            self.current = k + 1
            self._save_progress()
            self.publish_lights(frame("end", k + 1))
        else:
            self._save_progress()
            self.run_complete = True
            self.timer.cancel()
            self.get_logger().info(f"run complete: {self.n_changes} changes")
            self.finished = bool(self.graph["exit_when_done"])
        if k and k % 100 == 0:
            self.get_logger().info(f"change {k}/{self.n_changes}")

    def publish_change(self, k: int) -> None:
        self.current = k
        self._save_progress()
        frame_id, stamp_ns = frame("change", k), self.now_ns()
        event = self.events[k - 1] if k > 0 else None
        if event is not None:
            self.lights = event.lights
        # The lights first: the body (then the agent) waits for them, the
        # ground truth only goes to the recorder (a hand-over per change).
        tracing.stamp("environment.lights", k)
        self.publish_lights(frame_id, stamp_ns)
        if event is not None:
            header = messages.make_header(frame_id, stamp_ns)
            self.event_pub.publish(messages.table_to_cloud(
                {"index": event.index, "kind": KIND_CODES[event.kind],
                 "center_x": event.center[0], "center_y": event.center[1],
                 "grid_index": event.grid_index},
                contracts.contract("/environment/event").columns, header))

    def publish_current_lights(self) -> None:
        self.publish_lights(frame("end" if self.current > self.n_changes else "change",
                                  self.current))

    def publish_lights(self, frame_id: str, stamp_ns: int | None = None) -> None:
        self.lights_pub.publish(self.lights_packer.pack(
            np.asarray(self.lights), frame_id, self.now_ns() if stamp_ns is None else stamp_ns))


def main(args=None) -> int:
    return run_node(EnvironmentNode, "environment", args)


if __name__ == "__main__":
    raise SystemExit(main())
