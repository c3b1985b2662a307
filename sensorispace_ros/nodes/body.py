"""Body node: the simulated arm + retina (core.body.SimulatedBody).

Answers each ``/body/motor_command`` batch with one ``/body/sensation``
carrying the same header (the request id), and after each lights message a
one-row passive sensation of the resting arm (frame ``change/<k>`` or
``end/<k>``). Ground truth for the evaluator goes to ``/body/sensor_pose``
and ``/body/joint_states``; the agent never subscribes to those.
"""
from __future__ import annotations

import numpy as np

from .. import contracts, messages
from ..core import arm, retina
from ..core.body import SimulatedBody
from . import GraphNode, build_world, run_node


class BodyNode(GraphNode):

    def __init__(self, **kwargs):
        super().__init__("body", **kwargs)
        world = build_world(self.cfg)
        self.body = SimulatedBody(world.receptors, None, world.m0.copy())
        self.columns = {topic: contracts.contract(topic).columns for topic in (
            "/environment/lights", "/body/motor_command", "/body/sensation", "/body/sensor_pose")}
        self.sensation_pub = contracts.create_publisher(self, "/body/sensation")
        self.pose_pub = contracts.create_publisher(self, "/body/sensor_pose")
        self.joint_pub = contracts.create_publisher(self, "/body/joint_states")
        contracts.create_subscription(self, "/environment/lights", self.on_lights)
        contracts.create_subscription(self, "/body/motor_command", self.on_command)

    def on_lights(self, msg) -> None:
        decoded = self.decode("/environment/lights", msg, kinds=("change", "end"))
        if decoded is None:
            return
        (kind, _), lights = decoded
        if kind == "change":
            if len(lights) == 0:
                self.drop("/environment/lights", "no lights")
                return
            self.body.set_lights(lights)
        elif self.body.lights_world is None:
            self.drop("/environment/lights", "end of run before any lights")
            return
        self.publish_passive(msg.header)

    def publish_passive(self, header) -> None:
        """What the resting eye sees after a change. Not a query of the agent's: computed
        for the single resting pose exactly as the offline driver does
        (core.naive_evaluation._passive_sensation), so both runs see the same bits."""
        rest = self.body.motor_state
        pose = arm.forward(rest)
        sensation = retina.sensation(pose, self.body.lights_world, self.body.receptor_positions)
        self.sensation_pub.publish(messages.matrix_to_cloud(
            np.reshape(sensation, (1, -1)), self.columns["/body/sensation"], header))
        self.pose_pub.publish(messages.matrix_to_cloud(
            np.reshape(pose, (1, 3)), self.columns["/body/sensor_pose"], header))
        self.joint_pub.publish(messages.motor_to_joint_state(rest, header))

    def on_command(self, msg) -> None:
        decoded = self.decode("/body/motor_command", msg, kinds=("cmd",))
        if decoded is None:
            return
        _, motor = decoded
        if self.body.lights_world is None:
            self.drop("/body/motor_command", "no lights received yet")
            return
        if len(motor) == 0:
            self.drop("/body/motor_command", "empty batch")
            return
        self.answer(motor, msg.header)

    def answer(self, motor: np.ndarray, header) -> None:
        # One forward model per row for both replies (it was run twice: sense + sensor_pose);
        # the sensation goes first so the waiting agent proceeds while the ground truth is sent.
        sensations, poses = self.body.sense_with_poses(motor)
        self.sensation_pub.publish(messages.matrix_to_cloud(
            sensations, self.columns["/body/sensation"], header))
        self.pose_pub.publish(messages.matrix_to_cloud(
            poses.reshape(-1, 3), self.columns["/body/sensor_pose"], header))
        self.joint_pub.publish(messages.motor_to_joint_state(self.body.motor_state, header))


def main(args=None) -> int:
    return run_node(BodyNode, "body", args)


if __name__ == "__main__":
    raise SystemExit(main())
