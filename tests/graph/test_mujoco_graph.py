"""A MuJoCo body through the graph (one process): the body node renders the
model's camera and publishes its pixels as UINT8, the agent sizes itself from
the model's description, the run equals the offline naive run on the same
configuration, and the viewer shows the camera's image. Skipped, saying why,
where MuJoCo cannot render."""
import numpy as np
import pytest
import yaml
from rclpy.node import Node
from sensor_msgs.msg import Image

from sensorispace_ros import config
from sensorispace_ros.bodies.mujoco_render import rendering_problem
from sensorispace_ros.graph import in_process

from shared import REPO

PROBLEM = rendering_problem()
pytestmark = [pytest.mark.graph, pytest.mark.slow,
              pytest.mark.skipif(PROBLEM is not None, reason=f"MuJoCo cannot render: {PROBLEM}")]

MUJOCO_SMOKE = REPO / "config" / "mujoco-smoke.yaml"


def tiny_mujoco_config(tmp_path):
    """config/mujoco-smoke.yaml on a 3 x 3 grid (10 changes), the rank probes'
    clouds of 64 pairs: the graph's equality with the offline run, not what
    the agent finds, is tested here."""
    text = yaml.safe_load(MUJOCO_SMOKE.read_text())
    params = text["/**"]["ros__parameters"]
    params["world"]["grid_count"] = 3
    params["naive"] = {"cloud_pairs": 64}
    path = tmp_path / "mujoco-tiny.yaml"
    path.write_text(yaml.safe_dump(text))
    return path


class CameraWatcher(Node):
    """Keeps every /viewer/camera image."""

    def __init__(self, context):
        super().__init__("camera_watcher", context=context)
        self.images = []
        self.create_subscription(Image, "/viewer/camera", self.images.append, 100)


def test_mujoco_body_in_the_graph_equals_offline(tmp_path, domain_id):
    from sensorispace_ros.bodies import run_world
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.naive.run import run_naive
    from sensorispace_ros.graph.nodes.viewer import ViewerNode

    tiny = tiny_mujoco_config(tmp_path)
    cfg = config.load_config(tiny)
    world = run_world(cfg)
    offline = run_naive(world, NaiveParams(**cfg["naive"]))
    watchers = []

    def watch(context):
        watchers.append(CameraWatcher(context))
        return watchers[-1]

    # graph.command_timeout_s keeps its default (2 s): a rank cloud takes the
    # renderer longer than that under load, and the agent waits for it in
    # proportion to its rows rather than sending it again.
    result = in_process.run_graph_in_process(tiny, domain_id, tmp_path, timeout_s=600,
                                             extra_nodes=(watch,),
                                             node_factories={"viewer": ViewerNode})
    nodes = result["nodes"]
    description = nodes["agent"].description
    assert description.joint_names == ("joint1", "joint2", "joint3", "joint4")
    assert description.receptors == 256 and description.unit == "rad"
    assert nodes["representation"].description == description
    assert type(nodes["body"].body).__name__ == "MujocoBody"
    agent = nodes["agent"].agent
    np.testing.assert_array_equal(agent.points_of_view, offline.povs)
    assert agent.compensated == offline.agent.compensated
    assert agent.queries_total == offline.agent.queries_total
    assert agent.structure.metrics() == offline.agent.structure.metrics()
    images = watchers[0].images
    assert images, "the viewer showed no camera image"
    assert {(i.width, i.height, i.encoding) for i in images} == {(16, 16, "mono8")}
    assert any(max(i.data) > 20 for i in images)           # the spheres are in view
