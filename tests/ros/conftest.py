"""Every graph a test starts discovers on localhost only, in its own domain;
``context`` is a private rclpy Context there, for in-process nodes."""
import os
from pathlib import Path

import pytest

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

REPO = Path(__file__).resolve().parents[2]
SMOKE = REPO / "config" / "smoke.yaml"


@pytest.fixture
def domain_id():
    from sensorispace_ros.graph.dds_environment import free_domain_id
    return free_domain_id()


@pytest.fixture
def node_env(domain_id):
    from sensorispace_ros.graph.dds_environment import graph_environment
    return graph_environment(domain_id)


@pytest.fixture
def context(domain_id):
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    yield ctx
    ctx.try_shutdown()
