"""The body publishes its ground truth (``/body/sensor_pose``,
``/body/joint_states``) only while someone reads it (a recorder): looked at with
every change, so a run without a bag does not pack and publish ~120,000
messages nobody reads. The sensation always goes out. One body node on a
private context, driven by calling its callbacks with serialized messages."""
import time

import numpy as np

from sensorispace_ros import contracts, launcher, messages
from sensorispace_ros.nodes import build_world
from sensorispace_ros.nodes.body import BodyNode

from .conftest import SMOKE


class _Recording:
    """A publisher that records which topic each publication went to."""

    def __init__(self, publisher, log: list):
        self._publisher, self._log = publisher, log

    def publish(self, msg):
        self._log.append(self._publisher.topic_name)
        self._publisher.publish(msg)

    def get_subscription_count(self):
        return self._publisher.get_subscription_count()


def test_ground_truth_goes_out_only_while_read(context):
    body = BodyNode(context=context,
                    parameter_overrides=launcher.parameter_overrides(SMOKE, {}))
    reader = None
    try:
        log: list[str] = []
        for name in ("sensation_pub", "pose_pub", "joint_pub"):
            setattr(body, name, _Recording(getattr(body, name), log))
        lights = messages.CloudCdrPacker(contracts.contract("/environment/lights").columns)
        commands = messages.CloudCdrPacker(contracts.contract("/body/motor_command").columns)
        world = build_world(body.cfg)
        motor = np.array([[0.1, -1.5, 2.2, -3.0], [0.2, -1.4, 2.1, -2.9]])

        body.on_lights(lights.pack(np.asarray(world.initial_lights), "change/0", 1))
        body.on_command(commands.pack(motor, "cmd/1", 2))
        assert log == ["/body/sensation", "/body/sensation"]       # passive, answer

        reader = contracts.create_subscription(body, "/body/sensor_pose", lambda m: None)
        joints = contracts.create_subscription(body, "/body/joint_states", lambda m: None)
        deadline = time.monotonic() + 5.0
        while body.pose_pub.get_subscription_count() == 0 \
                or body.joint_pub.get_subscription_count() == 0:
            assert time.monotonic() < deadline, "the readers never matched"
            time.sleep(0.02)
        body.on_command(commands.pack(motor, "cmd/2", 3))         # same change: not yet
        assert log[2:] == ["/body/sensation"]
        body.on_lights(lights.pack(np.asarray(world.initial_lights) + 0.5, "change/1", 4))
        body.on_command(commands.pack(motor, "cmd/3", 5))
        assert log[3:] == ["/body/sensation", "/body/sensor_pose", "/body/joint_states"] * 2

        body.destroy_subscription(reader)
        body.destroy_subscription(joints)
        reader = None
        deadline = time.monotonic() + 5.0
        while body.pose_pub.get_subscription_count() > 0:
            assert time.monotonic() < deadline, "the readers never went away"
            time.sleep(0.02)
        body.on_lights(lights.pack(np.asarray(world.initial_lights), "change/2", 6))
        assert log[9:] == ["/body/sensation"]
    finally:
        body.destroy_node()
