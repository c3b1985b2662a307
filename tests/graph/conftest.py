"""The graph tests' fixtures on top of tests/conftest.py's ``domain_id``:
the environment of a node process there, and ``context``, a private rclpy
Context there, for in-process nodes."""
import pytest


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
