"""A MuJoCo body through the graph (one process): the body node renders the
model's camera and publishes its pixels as UINT8, the agent sizes itself from
the model's description, and the run equals the offline naive run on the same
configuration. Skipped, saying why, where MuJoCo cannot render."""
import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.bodies.mujoco_render import rendering_problem
from sensorispace_ros.graph import in_process

from shared import REPO

PROBLEM = rendering_problem()
pytestmark = [pytest.mark.graph, pytest.mark.slow,
              pytest.mark.skipif(PROBLEM is not None, reason=f"MuJoCo cannot render: {PROBLEM}")]

MUJOCO_SMOKE = REPO / "config" / "mujoco-smoke.yaml"


def test_mujoco_body_in_the_graph_equals_offline(tmp_path, domain_id):
    from sensorispace_ros.bodies import run_world
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.naive.run import run_naive

    cfg = config.load_config(MUJOCO_SMOKE)
    world = run_world(cfg)
    offline = run_naive(world, NaiveParams(**cfg["naive"]))
    result = in_process.run_graph_in_process(MUJOCO_SMOKE, domain_id, tmp_path, timeout_s=600)
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
