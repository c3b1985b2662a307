"""The graph on an imperfect body (docs/bodies.md): the body node draws the
noise the offline driver draws (commands and changes numbered alike), so the
naive agent in the graph makes every decision the offline agent makes; its
float32 sensations take the agent's fast read. Whatever the agent finds on
such a body, the comparison is of everything it measured and did."""
import numpy as np
import pytest
from sensor_msgs.msg import PointField

from sensorispace_ros import config, messages
from sensorispace_ros.graph import in_process

from shared import REPO

pytestmark = [pytest.mark.graph, pytest.mark.slow]

NOISY_SMOKE = REPO / "config" / "noisy-smoke.yaml"
# Lost frames left out: an agent that cannot take NaN stops on the first one,
# which would end the comparison early rather than test it.
NO_DROPOUT = {"world.retina.dropout": 0.0}


def _offline_agent(cfg, monkeypatch):
    """The offline naive agent and the passive sensations its driver gave it."""
    from sensorispace_ros.core.naive import run
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.run_world import run_world
    passive, driver_passive = [], run._passive_sensation

    def kept(body):
        passive.append(driver_passive(body))
        return passive[-1]
    monkeypatch.setattr(run, "_passive_sensation", kept)
    world = run_world(cfg)
    return run.run_naive(world, NaiveParams(**cfg["naive"])).agent, passive


class PassiveListener:
    """The passive sensations on /body/sensation (frame ``change/<k>``), by k."""

    def __init__(self, context):
        from rclpy.node import Node
        from sensor_msgs.msg import PointCloud2

        from sensorispace_ros import contracts
        from sensorispace_ros.core.body_description import BodyDescription
        self.node = Node("passive_listener", context=context)
        self.columns = contracts.contract("/body/sensation").columns_for(
            BodyDescription.revolute(4, 6))
        self.by_change: dict[int, np.ndarray] = {}
        self.node.create_subscription(PointCloud2, "/body/sensation", self.on_sensation,
                                      contracts.subscription_qos("/body/sensation"))

    def on_sensation(self, msg) -> None:
        kind, _, number = msg.header.frame_id.partition("/")
        if kind == "change":
            self.by_change[int(number)] = messages.cloud_to_matrix(msg, self.columns)[0]


def test_the_graph_senses_the_imperfect_body_as_the_offline_driver(tmp_path, domain_id,
                                                                    monkeypatch):
    cfg = config.load_config(NOISY_SMOKE, overrides=NO_DROPOUT)
    assert cfg["world"]["retina"]["dtype"] == "float32" and cfg["arm"]["motor_noise"] > 0
    config_path = tmp_path / "noisy.yaml"
    config_path.write_text(config.to_parameter_file(cfg))
    seen = {}

    def keep(nodes, replace):
        seen.update(nodes)
    listeners = []

    def listener(context):
        listeners.append(PassiveListener(context))
        return listeners[-1].node
    try:
        in_process.run_graph_in_process(config_path, domain_id, tmp_path / "run",
                                        timeout_s=600, on_spin=keep, extra_nodes=(listener,))
    except RuntimeError:
        pass               # a representation of too few POVs; the agent's run is over
    graph_node, (offline, offline_passive) = seen["agent"], _offline_agent(cfg, monkeypatch)
    # The passive sensation after change k (the graph's change/0 is the start,
    # which the offline driver does not sense): bit for bit.
    heard = listeners[0].by_change
    assert len(heard) > len(offline_passive) // 2
    for k, sensation in heard.items():
        if k >= 1:
            assert sensation.tobytes() == offline_passive[k - 1].astype(float).tobytes(), k
    graph = graph_node.agent
    assert graph_node.body.requests > 100
    assert (graph.calls_total, graph.queries_total) == (offline.calls_total, offline.queries_total)
    assert graph.calls_by_stage == offline.calls_by_stage
    assert graph.structure.metrics() == offline.structure.metrics()
    np.testing.assert_array_equal(graph.points_of_view, offline.points_of_view)
    # The body published float32 columns, and the agent read them by the fast path.
    published = messages.cloud_from_cdr(seen["body"].sensation_packer.pack(np.zeros((1, 6)), "x"))
    assert {field[2] for field in published.field_tuples} == {PointField.FLOAT32}
    assert graph_node.general_reads.get("/body/sensation", 0) == 0
    assert not graph_node.dropped
