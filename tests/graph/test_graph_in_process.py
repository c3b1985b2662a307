"""The whole graph in one process (one SingleThreadedExecutor, a private Context).

(a) the smoke run completes and equals the offline naive run on the same
config and seed, on the paper's body and on the same arm commanded in
degrees; (c) the live graph shows the agent subscribing only to
/body/sensation and the body's description, the representation only to
/agent/* and the description; (d) malformed messages on every subscribed
topic are dropped and change nothing.
"""
import array

import numpy as np
import pytest
from rclpy.node import Node
from std_msgs.msg import UInt64

from sensorispace_ros import config, contracts, messages
from sensorispace_ros.core.body_description import BodyDescription
from sensorispace_ros.graph import in_process
from sensorispace_ros.offline.representation import DIMENSIONS, build_representation

from shared import SMOKE

pytestmark = [pytest.mark.graph, pytest.mark.slow]

SUBSCRIBED = {node: contracts.topics_subscribed_by(node)
              for node in ("environment", "body", "agent", "representation")}
PAPER_BODY = BodyDescription.revolute(4, 6)
DESCRIPTION = "/body/description"


@pytest.fixture(scope="module")
def smoke_cfg():
    return config.load_config(SMOKE)


def _offline_run(cfg, description, produced=None):
    """The offline naive run (``produced`` when the caller has it) and its
    representation (of the POVs as angles)."""
    from sensorispace_ros.core.run_world import run_world
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.naive.run import run_naive
    if produced is None:
        produced = run_naive(run_world(cfg), NaiveParams(**cfg["naive"]))
    representation = build_representation(
        description.to_radians(produced.povs), produced.pairs, produced.set_ids, cfg,
        cfg["seed"])
    return produced, representation


@pytest.fixture(scope="module")
def offline(smoke_cfg, smoke_naive_run):
    return _offline_run(smoke_cfg, PAPER_BODY, smoke_naive_run)


# The smoke configuration with the paper's arm commanded in degrees.
SMOKE_IN_DEGREES = {"arm": {"motor_unit": "deg", "initial_motor_state": [
    5.729577951308232, -85.94366926962348, 126.05071492878111, -171.88733853924697]}}


class GraphObserver(Node):
    """Reads the live graph once the run is under way."""

    def __init__(self, context):
        super().__init__("graph_observer", context=context)
        self.subscriptions_by_node: dict | None = None

    def look(self, nodes) -> None:
        if self.subscriptions_by_node is None and nodes["agent"].last_passive >= 1:
            self.subscriptions_by_node = {
                name: sorted(topic for topic, _ in
                             self.get_subscriber_names_and_types_by_node(name, "/"))
                for name in SUBSCRIBED}


def _run(tmp_path, domain_id, extra_nodes=(), config_path=SMOKE):
    observers = []

    def make_observer(context):
        observers.append(GraphObserver(context))
        return observers[-1]

    result = in_process.run_graph_in_process(
        config_path, domain_id, tmp_path, extra_nodes=(make_observer, *extra_nodes),
        timeout_s=600, on_spin=lambda nodes, replace: observers[0].look(nodes))
    return result, observers[0]


def _assert_same_as_offline(result, offline):
    produced, representation = offline
    arrays = result["nodes"]["representation"].result
    agent = result["nodes"]["agent"].agent
    assert len(arrays["povs"]) == len(produced.povs)
    np.testing.assert_array_equal(arrays["povs"], produced.povs)
    np.testing.assert_array_equal(arrays["pairs"], produced.pairs)
    np.testing.assert_array_equal(arrays["set_ids"], produced.set_ids)
    assert agent.compensated == produced.agent.compensated
    for dim in DIMENSIONS:
        np.testing.assert_allclose(arrays[f"embedding_{dim}_before"], representation.before[dim],
                                   atol=1e-6, rtol=0)
        np.testing.assert_allclose(arrays[f"embedding_{dim}_iterations"],
                                   representation.iterations[dim], atol=1e-6, rtol=0)


def test_graph_equals_offline_and_agent_is_naive(tmp_path, domain_id, offline):
    result, observer = _run(tmp_path, domain_id)
    _assert_same_as_offline(result, offline)
    # Every change's sweep was sent with the settle before it and answered with the change.
    agent_node = result["nodes"]["agent"]
    assert agent_node.body.ahead_used == agent_node.agent.calls_by_stage["sweep"] > 100
    assert (tmp_path / "representation.npz").is_file()
    assert all(not node.dropped for node in result["nodes"].values()
               if hasattr(node, "dropped")), "an undisturbed run dropped messages"

    seen = observer.subscriptions_by_node
    assert seen is not None, "the observer never saw the running graph"
    assert seen["agent"] == [DESCRIPTION, "/body/sensation"]
    assert DESCRIPTION in seen["representation"] and all(
        t.startswith("/agent/") for t in seen["representation"] if t != DESCRIPTION)
    # The paper body described itself as the paper's: 4 joints in rad, 6 receptors.
    for name in ("agent", "representation"):
        assert result["nodes"][name].description == PAPER_BODY
    ground_truth = {t for t, c in contracts.load_contracts().items() if c.ground_truth}
    for name in ("agent", "representation"):
        assert not ground_truth & set(seen[name])
        assert not any(t.startswith("/environment/") for t in seen[name])
    for name, topics in SUBSCRIBED.items():
        assert seen[name] == sorted(topics), f"{name} does not subscribe as topics.yaml says"


def test_a_body_in_degrees_gives_the_offline_run_and_is_measured_in_angles(tmp_path, domain_id):
    cfg = config.load_config(SMOKE, overrides=config.flatten(SMOKE_IN_DEGREES))
    config_path = tmp_path / "smoke-degrees.yaml"
    config_path.write_text(config.to_parameter_file(cfg))
    degrees = BodyDescription.revolute(4, 6, "deg")
    result, _ = _run(tmp_path / "run", domain_id, config_path=config_path)
    for name in ("agent", "representation"):
        assert result["nodes"][name].description == degrees
    _assert_same_as_offline(result, _offline_run(cfg, degrees))
    povs = result["nodes"]["representation"].result["povs"]
    assert np.abs(povs).max() > 2 * np.pi          # kept in degrees in the arrays


# ---------------------------------------------------------------- (d) bad input

def _broken_clouds(topic: str, frame_id: str) -> list:
    """Malformed PointCloud2 messages for ``topic``, each wrong in one way."""
    columns = contracts.contract(topic).columns_for(PAPER_BODY)
    rows = 2

    def valid():
        table = {name: np.ones(rows) for name in columns}
        return messages.table_to_cloud(table, columns, messages.make_header(frame_id))

    broken = []
    msg = valid()                               # wrong size: data cut short
    msg.data = array.array("B", bytes(msg.data)[:-3])
    broken.append(msg)
    msg = valid()                               # width says more rows than data holds
    msg.width += 1
    msg.row_step += msg.point_step
    broken.append(msg)
    msg = valid()                               # wrong field layout: renamed column
    msg.fields[0].name = "bogus"
    broken.append(msg)
    msg = valid()                               # wrong field layout: shifted offset
    msg.fields[-1].offset += 1
    broken.append(msg)
    msg = valid()                               # wrong type of a column
    msg.fields[0].datatype = 7                  # FLOAT32
    broken.append(msg)
    float_columns = [n for n, kind in columns.items() if kind == "float64"]
    for bad in (np.nan, np.inf, -np.inf) if float_columns else ():   # non-finite values
        table = {name: np.ones(rows) for name in columns}
        table[float_columns[0]][1] = bad
        broken.append(messages.table_to_cloud(table, columns, messages.make_header(frame_id)))
    broken.append(messages.table_to_cloud(     # unknown frame id, valid layout
        {name: np.ones(rows) for name in columns}, columns, messages.make_header("bogus/1")))
    if topic in SERIALIZED_TOPICS:
        # Their subscribers take the bytes (raw=True): bytes that are no PointCloud2.
        from rclpy.serialization import serialize_message
        wire = serialize_message(valid())
        broken += [wire[:len(wire) // 2],                      # cut short
                   b"\x00\x00\x00\x00" + wire[4:],                # big-endian CDR
                   wire[:12] + b"\xff\xff\xff\x7f" + wire[16:],   # frame id length 2**31
                   bytes(np.random.default_rng(7).integers(0, 256, 300, dtype=np.uint8))]
    return broken


# Topics whose graph subscribers take serialized bytes (the probe topics, the lights).
SERIALIZED_TOPICS = ("/environment/lights", "/body/motor_command", "/body/sensation")


def _broken_descriptions() -> list:
    """Malformed /body/description messages, each wrong in one way."""
    broken = []
    for frame_id, names, periods, velocity in (
            ("rad", ["a"], [1.0], []), ("rad/0", ["a"], [1.0], []),
            ("furlong/6", ["a"], [1.0], []), ("rad/6", [], [], []),
            ("rad/6", ["a", "a"], [1.0, 1.0], []), ("rad/6", ["a"], [np.nan], []),
            ("rad/6", ["a", "b"], [1.0], []), ("rad/6", ["a"], [-1.0], []),
            ("rad/6", ["a"], [1.0], [0.0])):
        msg = messages.description_to_msg(PAPER_BODY)
        msg.header.frame_id, msg.name, msg.position, msg.velocity = (
            frame_id, names, periods, velocity)
        broken.append(msg)
    return broken


HOSTILE_FRAMES = {
    "/environment/lights": "change/1",
    "/body/motor_command": "cmd/1",
    "/body/hold": "hold/1",
    "/body/sensation": "cmd/1",
    "/agent/points_of_view": "change/1",
    "/agent/compensations": "change/1",
    "/agent/done": "end/1",
}


class HostilePublisher(Node):
    """Publishes malformed messages on every topic a graph node subscribes to."""

    def __init__(self, context):
        super().__init__("hostile", context=context)
        self.publishers_ = {t: contracts.create_publisher(self, t)
                            for t in (*HOSTILE_FRAMES, DESCRIPTION)}
        self.settled_pub = contracts.create_publisher(self, "/agent/settled")
        self.messages = {t: _broken_clouds(t, f) for t, f in HOSTILE_FRAMES.items()}
        self.messages[DESCRIPTION] = _broken_descriptions()
        self.sent = 0
        # A few per second: enough to cover every variant during a run without
        # turning the test into a load test (flooding is tests/reliability/test_fuzz.py).
        self.create_timer(0.25, self.fire)

    def fire(self) -> None:
        for topic, broken in self.messages.items():
            self.publishers_[topic].publish(broken[self.sent % len(broken)])
        # A settled number the environment is not waiting for.
        self.settled_pub.publish(UInt64(data=10 ** 9 + self.sent))
        self.sent += 1


def test_malformed_input_is_dropped_and_changes_nothing(tmp_path, domain_id, offline):
    hostile = []

    def make_hostile(context):
        hostile.append(HostilePublisher(context))
        return hostile[-1]

    result, _ = _run(tmp_path, domain_id, extra_nodes=(make_hostile,))
    assert hostile[0].sent >= len(_broken_clouds("/body/sensation", "cmd/1")), \
        "the run ended before every kind of malformed message was sent"
    _assert_same_as_offline(result, offline)
    nodes = result["nodes"]
    for name, topics in SUBSCRIBED.items():
        for topic in topics:
            assert nodes[name].dropped.get(topic, 0) > 0, f"{name} dropped nothing on {topic}"
