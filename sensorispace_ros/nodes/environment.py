"""Environment node: plays the world's schedule of object changes.

Publishes the hidden lights (``/environment/lights``, frame ``change/<k>``)
and the ground truth of each change (``/environment/event``); waits for the
agent's ``/agent/settled`` = k before the next change (the paper's static
environment during compensation). The end of the run is one more lights
message, ``end/<k>``, with unchanged lights: the body turns it into a passive
sensation, so the agent learns of the end only through its body.
"""
from __future__ import annotations

import numpy as np

from .. import contracts, messages
from ..core import world as world_mod
from . import GraphNode, build_world, frame, run_node

KIND_CODES = {world_mod.TRANSLATION: 0, world_mod.REDISTRIBUTION: 1}


class EnvironmentNode(GraphNode):

    def __init__(self, **kwargs):
        super().__init__("environment", **kwargs)
        self.world = build_world(self.cfg)
        self.n_changes = len(self.world.events)
        self.lights_pub = contracts.create_publisher(self, "/environment/lights")
        self.event_pub = contracts.create_publisher(self, "/environment/event")
        contracts.create_subscription(self, "/agent/settled", self.on_settled)
        self.current = -1              # number of the last change published (end = n + 1)
        self.settled = -1
        self.lights = self.world.initial_lights
        self.finished = False
        self.run_complete = False
        # Until the agent settles on the initial layout its subscription may
        # not be matched yet; volatile messages sent before are lost, so the
        # start is re-sent (the agent ignores duplicates).
        self.timer = self.create_timer(float(self.graph["resend_period_s"]), self.on_timer)
        self.get_logger().info(f"{self.n_changes} environmental changes scheduled")

    def on_timer(self) -> None:
        if self.current < 0:
            present = set(self.get_node_names())
            missing = [n for n in self.graph["wait_for_nodes"] if n not in present]
            if missing:
                self.get_logger().info(f"waiting for {', '.join(missing)}",
                                       throttle_duration_sec=5.0)
                return
            self.publish_change(0)
        elif self.settled < 0:
            self.publish_lights(frame("change", 0))

    def on_settled(self, msg) -> None:
        k = int(msg.data)
        if k != self.current or k <= self.settled:
            self.drop("/agent/settled", f"settled {k} while waiting for {self.current}")
            return
        self.settled = k
        if k < self.n_changes:
            self.publish_change(k + 1)
        elif k == self.n_changes:
            self.current = k + 1
            self.publish_lights(frame("end", k + 1))
        else:
            self.run_complete = True
            self.timer.cancel()
            self.get_logger().info(f"run complete: {self.n_changes} changes")
            self.finished = bool(self.graph["exit_when_done"])
        if k and k % 100 == 0:
            self.get_logger().info(f"change {k}/{self.n_changes}")

    def publish_change(self, k: int) -> None:
        self.current = k
        header = messages.make_header(frame("change", k), self.get_clock().now().nanoseconds)
        if k > 0:
            event = self.world.events[k - 1]
            self.lights = event.lights
            self.event_pub.publish(messages.table_to_cloud(
                {"index": event.index, "kind": KIND_CODES[event.kind],
                 "center_x": event.center[0], "center_y": event.center[1],
                 "grid_index": event.grid_index},
                contracts.contract("/environment/event").columns, header))
        self.publish_lights(header.frame_id, header)

    def publish_lights(self, frame_id: str, header=None) -> None:
        header = header or messages.make_header(frame_id, self.get_clock().now().nanoseconds)
        self.lights_pub.publish(messages.matrix_to_cloud(
            np.asarray(self.lights), contracts.contract("/environment/lights").columns, header))


def main(args=None) -> int:
    return run_node(EnvironmentNode, "environment", args)


if __name__ == "__main__":
    raise SystemExit(main())
