"""viewer: the run drawn for standard viewers (Foxglove, RViz), ground truth included.

The viewer is no part of the agent (which reads /body/sensation only) and
nothing in the graph reads what it publishes but the recorder. It follows
the world (/environment/lights), the body (/body/joint_states,
/body/sensor_pose, /body/sensation; best effort, so a display never holds
back the body's writers) and the agent's and the representation's outputs,
keeps them in a ``core.scene.Scene`` and publishes (msg_schemas/topics.yaml).
What is sized by the body (the POVs' motor columns, the joint names, the
receptors of /viewer/sensation) comes from the latched /body/description;
until it has come, the body's latest messages and the POVs wait for it.



  /viewer/scene               markers of the arm, its eye, the lights, the POVs found
  /viewer/representation_2d   each embedding as a coloured PointCloud2 (frame
  /viewer/representation_3d   ``representation``), coloured by true position
  /viewer/sensation           the receptors' latest outputs (Float64MultiArray)
  /viewer/camera              a MuJoCo body's latest camera image (Image)
  /viewer/activity            change, command, POVs and equality rows so far
  /viewer/stage_counters      the agent's stage counters at the end

The time series and the scene go out at most every VIEW_PERIOD_S, and only
when they changed. With ``graph.view_port`` set, the same bytes are also
served to the Foxglove app on ws://127.0.0.1:<port> (graph.live_view).
"""
from __future__ import annotations

import numpy as np
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState

from sensorispace_ros import config, contracts, messages
from sensorispace_ros.core import scene
from sensorispace_ros.graph.framework import GraphNode, build_world, run_node
from sensorispace_ros.protocol import EQUALITY_ROW_KINDS, WITHDRAWN

VIEW_PERIOD_S = 0.1
# The body's topics carry ~63,000 messages each in a paper run; the viewer wants
# the latest only, and must never make the body's reliable writers wait for it.
BODY_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                      reliability=ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)
ALL_FRAMES = ("change", "end", "cmd", "next")
EMBEDDING_DIMENSIONS = ("2d", "3d")


class ViewerNode(GraphNode):

    def __init__(self, **kwargs):
        super().__init__("viewer", **kwargs)
        world = build_world(self.cfg)
        self.scene = scene.Scene(world.receptors, self.cfg["world"]["retina"]["half_width"],
                                 ray_length=self.cfg["world"]["grid_half_width"],
                                 body_arm=world.arm)
        self.undrawable = 0
        # A MuJoCo body's receptors are a camera's pixels, shown as its image too.
        self.camera = (tuple(self.cfg["mujoco"]["image"])
                       if self.cfg["body"]["kind"] == "mujoco" else None)
        self.draw(self.scene.set_motor_state, world.m0)
        self.columns = {topic: self.columns_of(topic) for topic in (
            "/agent/compensations", "/agent/stage_counters",
            "/representation/embedding", "/viewer/representation_2d")}
        self.publishers_ = {topic: contracts.create_publisher(self, topic)
                            for topic in contracts.topics_published_by("viewer")}
        self.published = dict.fromkeys(self.publishers_, 0)
        self.live = self._start_live_view(int(self.graph["view_port"]))
        # What the body sent last (bytes, read at the next tick: one message a tick
        # is converted, not every one) and the run so far.
        self.latest = {"/body/sensation": None, "/body/sensor_pose": None,
                       "/body/joint_states": None}
        self.change = self.command = -1
        self.compensation_frames: set[str] = set()
        self.equality_rows = 0
        self.scene_changed = True
        self.activity_sent: tuple | None = None
        contracts.create_subscription(self, "/environment/lights", self.on_lights, raw=True)
        for topic in self.latest:
            self.create_subscription(contracts.contract(topic).msg_type, topic,
                                     self._keeper(topic), BODY_QOS, raw=True)
        self.subscribe_description(lambda description: None)
        contracts.create_subscription(self, "/agent/points_of_view", self.when_described(
            "/agent/points_of_view", self.on_points_of_view))
        contracts.create_subscription(self, "/agent/compensations", self.on_compensations)
        contracts.create_subscription(self, "/agent/stage_counters", self.on_stage_counters)
        contracts.create_subscription(self, "/representation/embedding", self.on_embedding)
        self.create_timer(VIEW_PERIOD_S, self.tick)

    def _start_live_view(self, port: int):
        if not port:
            return None
        from sensorispace_ros.graph.live_view import LiveView
        name = config.GRAPH_PREFIX + "view_port"
        if port > 65535:
            raise config.ConfigError(f"{name}: must be a port number in 1..65535, got {port}")
        try:
            live = LiveView(port, {t: contracts.contract(t).type_name for t in self.publishers_})
        except RuntimeError as exc:
            raise config.ConfigError(f"{name}: cannot serve the live view on port {port} "
                                     f"({exc})") from None
        self.get_logger().info(f"live view on {live.url} "
                               "(Foxglove: Open connection > Foxglove WebSocket)")
        return live

    # ------------------------------------------------------------ what comes in

    def _keeper(self, topic: str):
        def keep(raw: bytes) -> None:
            self.latest[topic] = raw
        return keep

    def on_lights(self, raw: bytes) -> None:
        read = self.read_float_cloud("/environment/lights", raw, kinds=("change", "end"))
        if read is None:
            return
        (kind, number), cloud = read
        if kind == "change" and len(cloud.matrix):
            self.scene.set_lights(cloud.matrix)
            self.scene_changed = True
        self.change = max(self.change, number)

    def _take_joint_state(self) -> None:
        raw, self.latest["/body/joint_states"] = self.latest["/body/joint_states"], None
        if raw is None:
            return
        names = contracts.contract("/body/joint_states").joint_names_for(self.description)
        try:
            motor_state = messages.joint_state_to_motor(deserialize_message(raw, JointState),
                                                        names)
        except messages.MessageError as exc:
            self.drop("/body/joint_states", str(exc))
            return
        except Exception as exc:            # bytes that are no JointState
            self.drop("/body/joint_states", f"{type(exc).__name__}: {exc}")
            return
        self.draw(self.scene.set_motor_state, motor_state)

    def on_points_of_view(self, msg) -> None:
        # end/<k>: POVs moved at the end of the run, drawn where they are now
        decoded = self.decode("/agent/points_of_view", msg, ("change", "end"), as_table=True)
        if decoded is None:
            return
        table = decoded[1]
        ids, first = np.unique(table["pov"], return_index=True)
        motor = np.column_stack([table[f"m{j}"][first]
                                 for j in range(self.description.n_motors)])
        self.draw(self.scene.add_points_of_view, ids, motor)

    def draw(self, change, *args) -> None:
        """``change(*args)`` of the scene (the world's planar chain); a body it
        cannot draw is said once and left undrawn."""
        try:
            change(*args)
        except ValueError as exc:
            if not self.undrawable:
                self.get_logger().warning(f"the scene cannot draw this body: {exc}")
            self.undrawable += 1
            return
        self.scene_changed = True

    def on_compensations(self, msg) -> None:
        decoded = self.decode("/agent/compensations", msg, EQUALITY_ROW_KINDS, as_table=True)
        if decoded is None or msg.header.frame_id in self.compensation_frames:
            return                          # a re-delivered reaction counts once
        self.compensation_frames.add(msg.header.frame_id)
        (kind, _), table = decoded
        self.equality_rows += -len(table) if kind == WITHDRAWN else len(table)

    def on_stage_counters(self, msg) -> None:
        decoded = self.decode("/agent/stage_counters", msg, ("end",), as_table=True)
        if decoded is None:
            return
        table = decoded[1]
        if len(table) != 1:
            self.drop("/agent/stage_counters", f"{len(table)} rows")
            return
        names = contracts.contract("/viewer/stage_counters").elements
        self.publish("/viewer/stage_counters", messages.values_to_multiarray(
            [float(table[name][0]) for name in names], names))

    def on_embedding(self, msg) -> None:
        dim = msg.header.frame_id.partition("/")[0]
        if dim not in EMBEDDING_DIMENSIONS:
            self.drop("/representation/embedding", f"frame id {msg.header.frame_id!r}")
            return
        try:
            table = messages.cloud_to_table(msg, self.columns["/representation/embedding"])
        except messages.MessageError as exc:
            self.drop("/representation/embedding", str(exc))
            return
        xyz = np.column_stack([table["x"], table["y"], table["z"]])
        self.publish(f"/viewer/representation_{dim}", messages.coloured_cloud(
            xyz, self.scene.representation_colours(table["pov"]), table["pov"],
            self.columns["/viewer/representation_2d"],
            messages.make_header(scene.REPRESENTATION_FRAME, self.now_ns())))

    # ------------------------------------------------------------ what goes out

    def tick(self) -> None:
        """Publish what changed since the last tick: the scene, the latest
        sensation, the run's counters (the body's messages once it is described)."""
        if self.description is not None:
            self._take_body_messages()
        if self.scene_changed:
            self.scene_changed = False
            self.publish("/viewer/scene", messages.shapes_to_marker_array(
                self.scene.shapes(), messages.make_header(scene.WORLD_FRAME, self.now_ns())))
        activity = (self.change, self.command, len(self.scene.pov_positions),
                    self.equality_rows)
        if activity != self.activity_sent:
            self.activity_sent = activity
            self.publish("/viewer/activity", messages.values_to_multiarray(
                activity, contracts.contract("/viewer/activity").elements))

    def _take_body_messages(self) -> None:
        self._take_joint_state()
        poses = self._take_latest("/body/sensor_pose")
        if poses is not None:
            (kind, number), cloud = poses
            self.scene.set_probes(cloud.matrix)
            self.scene_changed = True
            if kind == "cmd":
                self.command = max(self.command, number)
        sensation = self._take_latest("/body/sensation")
        if sensation is not None and len(sensation[1].matrix):
            self.publish("/viewer/sensation", messages.values_to_multiarray(
                sensation[1].matrix[-1],
                contracts.contract("/viewer/sensation").elements_for(self.description)))
            if self.camera is not None:
                self.publish("/viewer/camera", messages.pixels_to_image(
                    sensation[1].matrix[-1], *self.camera,
                    messages.make_header("camera", self.now_ns())))

    def _take_latest(self, topic: str):
        raw, self.latest[topic] = self.latest[topic], None
        return None if raw is None else self.read_float_cloud(topic, raw, ALL_FRAMES)

    def publish(self, topic: str, msg) -> None:
        """One serialization for ROS and, if it runs, the live view."""
        cdr = serialize_message(msg)
        self.publishers_[topic].publish(cdr)
        self.published[topic] += 1
        if self.live is not None:
            self.live.log(topic, cdr, self.now_ns())

    def close(self) -> None:
        live, self.live = self.live, None
        if live is not None:
            live.close()

    def destroy_node(self):
        self.close()
        return super().destroy_node()


def main(args=None) -> int:
    return run_node(ViewerNode, "viewer", args)


if __name__ == "__main__":
    raise SystemExit(main())
