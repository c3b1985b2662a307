"""What viewers draw: the viewer's messages decode as the standard types say,
its contract matches the topics it reads, and the live view serves them to a
Foxglove WebSocket client during a smoke run while the agent stays naive."""
import socket
import time

import numpy as np
import pytest
from rclpy.node import Node, NodeNameNonExistentError
from rclpy.serialization import deserialize_message
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import Marker, MarkerArray

from sensorispace_ros import contracts, messages
from sensorispace_ros.core import scene
from sensorispace_ros.core.body_description import BodyDescription
from sensorispace_ros.graph import in_process
from sensorispace_ros.graph.live_view import LiveView
from sensorispace_ros.graph.nodes.viewer import ViewerNode

from shared import SMOKE, free_port
from .foxglove_client import FoxgloveClient

STORE = get_typestore(Stores.ROS2_JAZZY)
VIEWER_TOPICS = contracts.topics_published_by("viewer")
CLOUD_COLUMNS = contracts.contract("/viewer/representation_2d").columns
PAPER_BODY = BodyDescription.revolute(4, 6)


def cdr(msg) -> bytes:
    from rclpy.serialization import serialize_message
    return serialize_message(msg)


def test_packed_rgb_holds_the_colour_in_its_bits():
    packed = messages.packed_rgb(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0],
                                           [1.0, 1.0, 1.0], [0.5, 0.25, 0.0]]))
    assert packed.dtype == np.float32
    assert packed.view(np.uint32).tolist() == [0xFF0000, 0x00FF00, 0x0000FF, 0xFFFFFF,
                                               (128 << 16) | (64 << 8)]
    with pytest.raises(ValueError, match="rgb"):
        messages.packed_rgb(np.array([[1.5, 0.0, 0.0]]))


def test_the_representation_cloud_has_float32_xyz_a_packed_rgb_and_the_pov_ids():
    xyz = np.array([[0.5, -1.0, 0.0], [2.0, 3.0, 0.25]])
    msg = messages.coloured_cloud(xyz, np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
                                  np.array([4, 9]), CLOUD_COLUMNS,
                                  messages.make_header(scene.REPRESENTATION_FRAME, 7))
    decoded = STORE.deserialize_cdr(cdr(msg), "sensor_msgs/msg/PointCloud2")  # not rclpy's reader
    assert decoded.header.frame_id == "representation"
    assert [(f.name, f.offset, f.datatype) for f in decoded.fields] == [
        ("x", 0, PointField.FLOAT32), ("y", 4, PointField.FLOAT32),
        ("z", 8, PointField.FLOAT32), ("rgb", 12, PointField.FLOAT32),
        ("pov", 16, PointField.UINT32)]
    assert (decoded.width, decoded.point_step, decoded.is_dense) == (2, 20, True)
    rows = np.frombuffer(decoded.data.tobytes(), dtype=np.dtype(
        [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<u4"), ("pov", "<u4")]))
    np.testing.assert_array_equal(np.column_stack([rows["x"], rows["y"], rows["z"]]), xyz)
    assert rows["rgb"].tolist() == [0xFF0000, 0x0000FF] and rows["pov"].tolist() == [4, 9]


def test_scene_shapes_become_markers_of_the_matching_type():
    view = scene.Scene(np.linspace(-1, 1, 6), 1.0, 6.0)
    view.set_motor_state([0.1, -1.5, 2.2, -3.0])
    view.set_lights(np.array([[4.0, 1.0], [5.0, -2.0], [-4.0, 3.0]]))
    view.set_probes(np.array([[1.0, 1.0, 0.0]]))
    array = deserialize_message(cdr(messages.shapes_to_marker_array(
        view.shapes(), messages.make_header(scene.WORLD_FRAME, 5))), MarkerArray)
    markers = {m.ns: m for m in array.markers}
    expected = {"arm": Marker.LINE_STRIP, "joints": Marker.SPHERE_LIST,
                "field_of_view": Marker.LINE_LIST, "receptors": Marker.LINE_LIST,
                "lights": Marker.SPHERE_LIST, "probes": Marker.POINTS}
    assert {ns: m.type for ns, m in markers.items()} == expected
    for marker in array.markers:
        assert marker.header.frame_id == "world" and marker.action == Marker.ADD
        assert marker.pose.orientation.w == 1.0 and marker.scale.x > 0 and marker.color.a > 0
    assert [(p.x, p.y) for p in markers["lights"].points] == [(4, 1), (5, -2), (-4, 3)]
    tip = markers["arm"].points[-1]
    assert (tip.x, tip.y) == pytest.approx(tuple(scene.arm_joint_positions(
        [0.1, -1.5, 2.2, -3.0])[-1]))


def test_series_are_multiarrays_named_by_their_contract():
    names = contracts.contract("/viewer/sensation").elements_for(PAPER_BODY)
    msg = deserialize_message(cdr(messages.values_to_multiarray(np.arange(6.0), names)),
                              Float64MultiArray)
    assert list(msg.data) == [0, 1, 2, 3, 4, 5]
    assert msg.layout.dim[0].label.split(",") == list(names) == [f"s{i}" for i in range(6)]
    with pytest.raises(ValueError, match="labels"):
        messages.values_to_multiarray([1.0], names)


def test_the_viewer_contract_follows_the_topics_it_shows():
    for body in (PAPER_BODY, BodyDescription.revolute(2, 3, "deg")):
        assert contracts.contract("/viewer/sensation").elements_for(body) == tuple(
            contracts.contract("/body/sensation").columns_for(body))
    assert contracts.contract("/viewer/stage_counters").elements == tuple(
        contracts.contract("/agent/stage_counters").columns)
    assert set(VIEWER_TOPICS) == {"/viewer/scene", "/viewer/representation_2d",
                                  "/viewer/representation_3d", "/viewer/sensation",
                                  "/viewer/activity", "/viewer/stage_counters",
                                  "/viewer/camera"}
    for topic in VIEWER_TOPICS:
        spec = contracts.contract(topic)
        assert spec.subscribers == ("recorder",), topic   # nothing of the graph reads them
        assert spec.type_name in STORE.types, topic         # the recorder can store them
        if spec.type_name == "std_msgs/msg/Float64MultiArray":
            assert spec.element_spec, topic
    # the viewer may read ground truth; the agent and the representation still do not
    for node in ("agent", "representation"):
        assert not {t for t in contracts.topics_subscribed_by(node)
                    if contracts.contract(t).ground_truth}


def test_the_live_view_advertises_ros2msg_channels_and_sends_cdr():
    port = free_port()
    live = LiveView(port, {"/viewer/sensation": "std_msgs/msg/Float64MultiArray"})
    client = FoxgloveClient(live.url).start()
    try:
        sent = cdr(messages.values_to_multiarray(
            np.arange(6.0) / 10, contracts.contract("/viewer/sensation").elements_for(PAPER_BODY)))
        deadline = time.monotonic() + 30
        while not client.received("/viewer/sensation") and time.monotonic() < deadline:
            live.log("/viewer/sensation", sent, time.time_ns())   # dropped until subscribed
            time.sleep(0.05)
        assert client.error is None, client.error
        assert client.subprotocol == "foxglove.sdk.v1"
        (channel,) = client.channels.values()
        assert (channel["topic"], channel["encoding"], channel["schemaEncoding"],
                channel["schemaName"]) == ("/viewer/sensation", "cdr", "ros2msg",
                                           "std_msgs/msg/Float64MultiArray")
        assert "MSG: std_msgs/MultiArrayLayout" in channel["schema"]
        _, payload = client.received("/viewer/sensation")[0]
        assert payload == sent
        assert list(deserialize_message(payload, Float64MultiArray).data) == pytest.approx(
            np.arange(6.0) / 10)
    finally:
        client.stop()
        live.close()
    with pytest.raises(ValueError, match="port"):
        LiveView(70000, {})


def test_a_busy_port_stops_the_viewer_naming_the_parameter(context):
    from sensorispace_ros.config import ConfigError
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(ConfigError, match=rf"^graph\.view_port: cannot serve .* {port}"):
            ViewerNode(context=context, parameter_overrides=in_process.parameter_overrides(
                SMOKE, {"graph.view_port": port}))


def test_the_viewer_drops_malformed_messages_and_draws_on(context):
    from std_msgs.msg import Header

    viewer = ViewerNode(context=context,
                        parameter_overrides=in_process.parameter_overrides(SMOKE))
    try:
        viewer.on_description(messages.description_to_msg(PAPER_BODY))
        lights = contracts.contract("/environment/lights").columns
        good = messages.CloudCdrPacker(lights).pack(np.array([[4.0, 1.0], [5.0, 2.0]]), "change/0")
        viewer.on_lights(b"\x00\x01\x00\x00junk")
        viewer.on_lights(messages.CloudCdrPacker(lights).pack(np.ones((1, 2)), "cmd/3"))
        viewer.on_lights(good)
        for topic in ("/body/sensation", "/body/sensor_pose", "/body/joint_states"):
            viewer._keeper(topic)(b"\x00\x01\x00\x00not a message")
        viewer.tick()
        bad_embedding = messages.table_to_cloud(
            {"pov": [1], "x": [0.0], "y": [0.0], "z": [0.0]},
            contracts.contract("/representation/embedding").columns,
            Header(frame_id="4d/iteration/0"))
        viewer.on_embedding(bad_embedding)
        assert set(viewer.dropped) == {"/environment/lights", "/body/sensation",
                                       "/body/sensor_pose", "/body/joint_states",
                                       "/representation/embedding"}, viewer.dropped
        assert viewer.dropped["/environment/lights"] == 2
        np.testing.assert_array_equal(viewer.scene.lights, [[4.0, 1.0], [5.0, 2.0]])
        assert viewer.published["/viewer/scene"] == 1 and viewer.change == 0
        assert viewer.published["/viewer/representation_2d"] == 0
    finally:
        viewer.destroy_node()


def test_the_viewer_draws_the_planar_chain_of_the_configured_body(context):
    from shared import REPO

    viewer = ViewerNode(context=context, parameter_overrides=in_process.parameter_overrides(
        REPO / "config" / "bodies" / "five-joint.yaml"))
    try:
        # The start drawn at init: four links of 0.75 from the base to the eye.
        assert viewer.undrawable == 0
        arm_points = {s.namespace: s for s in viewer.scene.shapes()}["arm"].points
        assert len(arm_points) == 5
        np.testing.assert_allclose(np.linalg.norm(np.diff(arm_points, axis=0), axis=1), 0.75)
    finally:
        viewer.destroy_node()


# ---------------------------------------------------------------- a smoke run, viewed live

class SubscriptionObserver(Node):
    """Every topic each node subscribed, as discovery shows it from the first
    passive sensation to the end of the run (on a loaded machine one look may
    come before the viewer's subscriptions are discovered)."""

    def __init__(self, context):
        super().__init__("viewer_observer", context=context)
        self.topics = {name: set() for name in ("agent", "representation", "viewer")}
        self._last_look = 0.0

    @property
    def seen(self) -> dict:
        return {name: sorted(topics) for name, topics in self.topics.items()}

    def look(self, nodes) -> None:
        if nodes["agent"].last_passive < 1 or time.monotonic() - self._last_look < 0.5:
            return
        self._last_look = time.monotonic()
        for name, topics in self.topics.items():
            try:
                found = self.get_subscriber_names_and_types_by_node(name, "/")
            except NodeNameNonExistentError:     # not discovered yet
                continue
            topics.update(t for t, _ in found)


def _final_embedding_arrived(client, n_povs) -> bool:
    for topic in ("/viewer/representation_2d", "/viewer/representation_3d"):
        clouds = [deserialize_message(p, PointCloud2) for _, p in client.received(topic)]
        if not clouds or clouds[-1].width != n_povs:
            return False
    return True


@pytest.mark.graph
@pytest.mark.slow
def test_a_smoke_run_is_served_to_a_foxglove_client_and_the_agent_stays_naive(
        tmp_path, domain_id):
    port = free_port()
    client = FoxgloveClient(f"ws://127.0.0.1:{port}").start()
    observers = []

    def observe(context):
        observers.append(SubscriptionObserver(context))
        return observers[-1]

    def on_spin(nodes, replace):
        observers[0].look(nodes)
        representation = nodes["representation"].result
        if representation is None:
            return
        # The run is over: keep spinning until the client has the last embeddings.
        deadline = time.monotonic() + 30
        while (not _final_embedding_arrived(client, len(representation["pov_ids"]))
               and time.monotonic() < deadline):
            nodes["viewer"].spin_once(0.05)

    try:
        result = in_process.run_graph_in_process(
            SMOKE, domain_id, tmp_path, extra_nodes=(observe,), timeout_s=600, on_spin=on_spin,
            parameters={"graph.view_port": port}, node_factories={"viewer": ViewerNode})
    finally:
        client.stop()
    assert client.error is None, client.error
    viewer = result["nodes"]["viewer"]
    assert not viewer.dropped, viewer.dropped

    # naivety holds with the viewer in the graph; the viewer reads what its contract says
    seen = observers[0].seen
    assert seen["agent"] == ["/body/description", "/body/sensation"]
    assert "/body/description" in seen["representation"] and all(
        t.startswith("/agent/") for t in seen["representation"] if t != "/body/description")
    assert seen["viewer"] == sorted(contracts.topics_subscribed_by("viewer"))

    advertised = {c["topic"]: c for c in client.channels.values()}
    assert set(advertised) == set(VIEWER_TOPICS)
    for topic, channel in advertised.items():
        assert channel["schemaName"] == contracts.contract(topic).type_name
        assert channel["encoding"] == "cdr" and channel["schemaEncoding"] == "ros2msg"

    scenes = [deserialize_message(p, MarkerArray) for _, p in client.received("/viewer/scene")]
    assert len(scenes) > 3
    last = {m.ns: m for m in scenes[-1].markers}
    assert {"arm", "joints", "field_of_view", "lights", "points_of_view"} <= set(last)
    n_povs = len(result["nodes"]["representation"].result["pov_ids"])
    assert len(last["points_of_view"].points) == n_povs
    assert len(last["lights"].points) == result["nodes"]["environment"].cfg[
        "world"]["lights"]["count"]

    sensations = [deserialize_message(p, Float64MultiArray).data
                  for _, p in client.received("/viewer/sensation")]
    assert len(sensations) > 3 and all(len(s) == 6 and np.all(np.isfinite(s))
                                       for s in sensations)
    activity = [list(deserialize_message(p, Float64MultiArray).data)
                for _, p in client.received("/viewer/activity")]
    change, command, povs, rows = activity[-1]
    assert povs == n_povs and command > 0 and change >= 1
    assert rows == len(result["nodes"]["representation"].result["pairs"])
    assert np.all(np.diff(np.array(activity), axis=0) >= 0)   # counters only grow

    (_, counters), = client.received("/viewer/stage_counters")
    agent = result["nodes"]["agent"].agent
    names = contracts.contract("/viewer/stage_counters").elements
    values = dict(zip(names, deserialize_message(counters, Float64MultiArray).data))
    assert values["calls_sweep"] == agent.calls_by_stage["sweep"] > 0

    final = deserialize_message(client.received("/viewer/representation_2d")[-1][1], PointCloud2)
    rows = messages.cloud_to_table(final, CLOUD_COLUMNS)
    arrays = result["nodes"]["representation"].result
    np.testing.assert_array_equal(rows["pov"], arrays["pov_ids"])
    np.testing.assert_allclose(np.column_stack([rows["x"], rows["y"]]),
                               arrays["embedding_2d_iterations"][-1], rtol=1e-6, atol=1e-5)
    assert np.all(rows["z"] == 0)
    assert len(set(rows["rgb"].view(np.uint32).tolist())) > 1     # coloured by position


def _layout_panels(node) -> list[str]:
    if isinstance(node, str):
        return [node]
    return _layout_panels(node["first"]) + _layout_panels(node["second"])


def test_the_foxglove_layout_shows_the_viewer_topics_in_their_frames():
    import json
    import re

    from shared import REPO

    layout = json.loads((REPO / "docs" / "foxglove-layout.json").read_text())
    panels = layout["configById"]
    assert sorted(_layout_panels(layout["layout"])) == sorted(panels)
    three_d = {k: v for k, v in panels.items() if k.startswith("3D!")}
    plots = {k: v for k, v in panels.items() if k.startswith("Plot!")}
    assert three_d and plots
    shown = set()
    for config in three_d.values():
        for topic, settings in config["topics"].items():
            spec = contracts.contract(topic)
            shown.add(topic)
            if settings.get("visible"):                       # drawn in the frame it follows
                assert spec.frame_id == config["followTf"], topic
            if spec.type_name == "sensor_msgs/msg/PointCloud2":
                assert settings["colorField"] in spec.columns and settings["colorMode"] == "rgb"
    assert {"/viewer/scene", "/viewer/representation_2d"} <= shown
    for config in plots.values():
        for path in config["paths"]:
            topic, index = re.fullmatch(r"(/[\w/]+)\.data\[(\d+)\]", path["value"]).groups()
            # The layout plots the paper's body (6 receptors).
            elements = contracts.contract(topic).elements_for(PAPER_BODY)
            assert int(index) < len(elements)
            assert path["label"].replace(" ", "_") == elements[int(index)], path


@pytest.mark.graph
@pytest.mark.slow
def test_launch_with_view_serves_the_run_and_records_the_viewer_topics(tmp_path, domain_id):
    import os
    import re
    import signal
    import subprocess
    import sys

    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from shared import REPO

    port = free_port()
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               PYTHONPATH=os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH"))
                                          if p))
    client = FoxgloveClient(f"ws://127.0.0.1:{port}", connect_timeout_s=120).start()
    proc = subprocess.Popen(
        [sys.executable, "-m", "sensorispace_ros.cli", "launch", "--config", str(SMOKE),
         "--run", "viewed", "--domain-id", str(domain_id), "--results", str(tmp_path / "results"),
         "--timeout", "400", "--view-port", str(port)],
        cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        output, _ = proc.communicate(timeout=450)
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
        client.stop()
    assert proc.returncode == 0, output
    assert f"live view on ws://127.0.0.1:{port}" in output
    assert re.search(r"started viewer \(pid \d+\)", output), output
    for pid in re.findall(r"started \w+ \(pid (\d+)\)", output):
        with pytest.raises(ProcessLookupError):
            os.kill(int(pid), 0)                   # the viewer was stopped with the rest
    assert client.error is None, client.error
    assert {c["topic"] for c in client.channels.values()} == set(VIEWER_TOPICS)
    scenes = client.received("/viewer/scene")
    assert scenes and deserialize_message(scenes[-1][1], MarkerArray).markers

    # The bag holds the viewer's topics; an MCAP reader with ROS 2 decoding (as
    # Foxglove's) decodes them from the bag's own schemas.
    mcap = tmp_path / "bags" / "viewed" / "viewed.mcap"
    counts, namespaces = {}, set()
    with open(mcap, "rb") as stream:
        for _, channel, _, decoded in make_reader(
                stream, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                topics=list(VIEWER_TOPICS)):
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/viewer/scene":
                namespaces.update(m.ns for m in decoded.markers)
    assert counts.get("/viewer/scene", 0) > 3 and counts.get("/viewer/sensation", 0) > 3, counts
    assert counts.get("/viewer/representation_2d", 0) >= 1, counts
    assert {"arm", "joints", "field_of_view", "lights", "points_of_view"} <= namespaces
