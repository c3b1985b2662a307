"""The representation node's chain pool: started with the node,
and none of its processes outlives the node, whether it is destroyed, stopped
by SIGTERM or killed."""
from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from shared import SMOKE

READY = re.compile(r"chain pool ready in [0-9.]+ s, worker pids \[(\d+), (\d+)\]")


def alive(pid: int) -> bool:
    """Running (a zombie left to a PID 1 that does not reap is not)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def descendants(pid: int) -> set[int]:
    """Every living process below ``pid`` (from /proc: parent of each process)."""
    parents = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            parents[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    found, frontier = set(), {pid}
    while frontier:
        frontier = {child for child, parent in parents.items() if parent in frontier}
        found |= frontier
    return found


def wait_until(predicate, timeout_s: float, step_s: float = 0.1) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(step_s)
    return predicate()


def test_destroying_the_node_ends_its_pool_workers(domain_id, tmp_path):
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    from sensorispace_ros.offline import chain_pool
    from sensorispace_ros.graph.in_process import parameter_overrides
    from sensorispace_ros.graph.nodes.representation import RepresentationNode

    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = RepresentationNode(context=context, parameter_overrides=parameter_overrides(
            SMOKE, {"graph.results_dir": str(tmp_path)}))
        node.chain_pool_starter.join(timeout=120)
        assert node.chain_pool is not None, "the pool did not start"
        pids = chain_pool.chain_pool_pids(node.chain_pool)
        assert len(pids) == 2 and all(alive(pid) for pid in pids)
        node.destroy_node()
        assert node.chain_pool is None
        assert not any(alive(pid) for pid in pids)
    finally:
        context.try_shutdown()


def test_the_pool_starts_late_or_as_soon_as_the_run_is_over(domain_id, tmp_path, monkeypatch):
    # Started CHAIN_POOL_DELAY_S after the node (the other nodes' start-up
    # first), or at once when /agent/done arrives.
    import numpy as np
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    from sensorispace_ros import contracts, messages
    from sensorispace_ros.graph.in_process import parameter_overrides
    from sensorispace_ros.graph.nodes import representation

    monkeypatch.setattr(representation, "CHAIN_POOL_DELAY_S", 3600.0)
    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = representation.RepresentationNode(context=context, parameter_overrides=
                                                 parameter_overrides(SMOKE, {
                                                     "graph.results_dir": str(tmp_path)}))
        node.build = lambda: None
        node.chain_pool_starter.join(timeout=2.0)
        assert node.chain_pool_starter.is_alive() and node.chain_pool is None
        node.on_done(messages.table_to_cloud(
            {"changes": np.array([3]), "points_of_view": np.array([4]),
             "compensation_rows": np.array([4]), "compensated": np.array([2]),
             "queries": np.array([1]), "calls": np.array([1]), "moved_povs": np.array([0])},
            contracts.contract("/agent/done").columns, messages.make_header("end/3")))
        node.chain_pool_starter.join(timeout=120)
        assert node.chain_pool is not None, "the pool did not start at /agent/done"
        node.destroy_node()
    finally:
        context.try_shutdown()


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGKILL], ids=["sigterm", "sigkill"])
def test_no_process_of_the_node_outlives_it(stop, node_env, tmp_path):
    """Started as the launcher starts it; its process tree (forkserver,
    resource tracker, the two workers) is gone soon after it stops, even when
    SIGKILL gives it no chance to clean up."""
    log = tmp_path / "representation.log"
    with open(log, "w") as out:
        node = subprocess.Popen(
            [sys.executable, "-m", "sensorispace_ros.graph.nodes.representation", "--ros-args",
             "--params-file", str(SMOKE), "-p", f"graph.results_dir:={tmp_path}"],
            env=node_env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        assert wait_until(lambda: READY.search(log.read_text()), 120), log.read_text()
        workers = {int(pid) for pid in READY.search(log.read_text()).groups()}
        tree = descendants(node.pid)
        assert workers <= tree and len(tree) >= 3      # + the forkserver
        node.send_signal(stop)
        node.wait(timeout=30)
        if stop == signal.SIGTERM:
            assert node.returncode == 0, log.read_text()
            assert not any(alive(pid) for pid in workers)   # ended before the node exited
        assert wait_until(lambda: not any(alive(pid) for pid in tree), 15), \
            f"left over: {sorted(pid for pid in tree if alive(pid))}"
        assert "Traceback" not in log.read_text()
    finally:
        if node.poll() is None:
            node.kill()
            node.wait()
