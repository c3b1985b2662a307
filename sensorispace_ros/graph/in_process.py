"""The whole graph in one process: every node on one SingleThreadedExecutor with
a private Context, for tests and benches (``run_graph_in_process``), and the
parameter file as rclpy Parameters for a node built in-process
(``parameter_overrides``)."""
from __future__ import annotations

import os
import time
from pathlib import Path


def parameter_overrides(config_path: str | Path, graph: dict | None = None) -> list:
    """The parameter file (and ``graph.*`` values) as rclpy Parameters, for in-process nodes."""
    from rclpy.parameter import Parameter

    from sensorispace_ros import config
    flat = config.flatten(config.read_parameter_file(config_path))
    flat.update(graph or {})
    return [Parameter(name, value=value) for name, value in flat.items()]


def _graph_nodes() -> dict:
    from sensorispace_ros.graph.nodes.agent import AgentNode
    from sensorispace_ros.graph.nodes.body import BodyNode
    from sensorispace_ros.graph.nodes.environment import EnvironmentNode
    from sensorispace_ros.graph.nodes.representation import RepresentationNode

    return {"representation": RepresentationNode, "body": BodyNode, "agent": AgentNode,
            "environment": EnvironmentNode}


class _InProcessGraph:
    """The nodes of one in-process run and the executor that spins them."""

    def __init__(self, context, overrides: list, factories: dict):
        from rclpy.executors import SingleThreadedExecutor

        self.context = context
        self.overrides = overrides
        self.factories = factories
        self.nodes: dict = {}
        self.executor = SingleThreadedExecutor(context=context)

    def add(self, name: str, node) -> None:
        node.spin_once = lambda timeout_s: self.executor.spin_once(timeout_sec=timeout_s)
        self.executor.add_node(node)
        self.nodes[name] = node

    def make(self, name: str) -> None:
        self.add(name, self.factories[name](context=self.context,
                                            parameter_overrides=self.overrides))

    def replace(self, name: str):
        """Destroy node ``name``, put a fresh one from its factory in its place;
        returns the old one."""
        old = self.nodes[name]
        self.executor.remove_node(old)
        old.destroy_node()
        self.make(name)
        return old

    def spin_until_done(self, timeout_s: float, on_spin) -> float:
        """Spin until the representation is written; returns the wall time."""
        nodes = self.nodes
        started = time.monotonic()
        while nodes["representation"].result is None:
            if nodes["agent"].finished or nodes["representation"].finished:
                raise RuntimeError("a node failed; see its log")
            if time.monotonic() - started > timeout_s:
                raise TimeoutError(f"graph did not finish within {timeout_s} s")
            self.executor.spin_once(timeout_sec=0.1)
            for node in nodes.values():
                step = getattr(node, "step", None)
                if step is not None:
                    step()
            if on_spin is not None:
                on_spin(nodes, self.replace)
        return time.monotonic() - started

    def close(self) -> None:
        if "agent" in self.nodes:
            self.nodes["agent"].abort()      # unblocks the agent's worker if it still waits
        self.executor.shutdown()
        for node in self.nodes.values():
            node.destroy_node()


def run_graph_in_process(config_path: str | Path, domain_id: int, results_dir: str | Path,
                         extra_nodes=(), timeout_s: float = 600.0, on_spin=None,
                         parameters: dict | None = None, node_factories: dict | None = None
                         ) -> dict:
    """All four nodes in this process on one SingleThreadedExecutor and a private Context.

    ``extra_nodes``: callables ``context -> Node`` added to the same executor
    (tests add observers or hostile publishers). ``on_spin(nodes, replace)`` is
    called after every spin; ``replace(name)`` destroys that node, puts a fresh
    one from its factory in its place and returns the old one (tests "kill" and
    restart a node). ``parameters``: more ``graph.*`` parameters for every node;
    ``node_factories``: ``name -> callable(context=, parameter_overrides=)``
    in place of a node class. Returns ``{"nodes": {...}, "wall_s": ...}`` once
    the representation is written; raises TimeoutError otherwise.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    context = Context()
    rclpy.init(context=context, domain_id=int(domain_id),
               signal_handler_options=SignalHandlerOptions.NO)
    overrides = parameter_overrides(config_path, {"graph.results_dir": str(results_dir),
                                                  "graph.resend_period_s": 0.5,
                                                  "graph.exit_when_done": False,
                                                  **(parameters or {})})
    graph = _InProcessGraph(context, overrides, {**_graph_nodes(), **(node_factories or {})})
    try:
        for name in graph.factories:
            graph.make(name)
        for k, make in enumerate(extra_nodes):
            graph.add(f"extra{k}", make(context))
        wall_s = graph.spin_until_done(timeout_s, on_spin)
        return {"nodes": graph.nodes, "wall_s": wall_s}
    finally:
        graph.close()
        context.try_shutdown()
