"""(b) `sensorispace launch`: one process per node, a run to completion, a killed node named.

Also (c) on the multi-process graph: the live graph, read from another
participant, shows the agent subscribing only to /body/sensation and the
representation only to /agent/*.
"""
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time

import pytest
import rclpy
from rclpy.context import Context
from rclpy.signals import SignalHandlerOptions

from .conftest import REPO, SMOKE

pytestmark = [pytest.mark.graph, pytest.mark.slow]


def _launch(tmp_path, domain_id, run, env):
    command = [sys.executable, "-m", "sensorispace_ros.cli", "launch", "--config", str(SMOKE),
               "--run", run, "--domain-id", str(domain_id), "--no-record",
               "--results", str(tmp_path / "results"), "--timeout", "400"]
    return subprocess.Popen(command, cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)


def _read_lines(proc, lines: list) -> threading.Thread:
    def pump():
        for line in proc.stdout:
            lines.append(line)
    thread = threading.Thread(target=pump, daemon=True)
    thread.start()
    return thread


def _stop(proc) -> None:
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()


def _launcher_env():
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH")) if p)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    return env


def _subscriptions_of(domain_id: int, names, deadline_s: float = 60.0) -> dict:
    """Topics each node subscribes to, read from the live graph by another participant."""
    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("naivety_observer", context=context)
    try:
        deadline = time.monotonic() + deadline_s
        seen = {}
        while time.monotonic() < deadline:
            present = set(node.get_node_names())
            if all(n in present for n in names):
                seen = {n: sorted(t for t, _ in node.get_subscriber_names_and_types_by_node(n, "/"))
                        for n in names}
                if all(seen.values()):
                    return seen
            time.sleep(0.2)
        return seen
    finally:
        node.destroy_node()
        context.try_shutdown()


def test_launch_runs_the_smoke_config_and_the_agent_is_naive(tmp_path, domain_id):
    lines: list = []
    proc = _launch(tmp_path, domain_id, "smoke", _launcher_env())
    try:
        pump = _read_lines(proc, lines)
        seen = _subscriptions_of(domain_id, ("agent", "representation", "body"))
        proc.wait(timeout=450)
        pump.join(timeout=5)
    finally:
        _stop(proc)
    output = "".join(lines)
    assert proc.returncode == 0, output
    assert f"ROS_DOMAIN_ID={domain_id}" in output and "LOCALHOST" in output
    assert seen.get("agent") == ["/body/sensation"], seen
    assert seen.get("representation") and all(
        t.startswith("/agent/") for t in seen["representation"]), seen
    assert "/environment/lights" in seen.get("body", [])
    metrics = json.loads((tmp_path / "results" / "smoke" / "metrics.json").read_text())
    # The agent's own counters made it through /agent/done to the evaluator.
    assert metrics["pov"]["count"] == metrics["agent"]["points_of_view"] > 3
    assert metrics["exploration"]["compensated"] == metrics["agent"]["compensated"] > 0
    assert "after" in metrics["quality"]["2d"]
    for pid in re.findall(r"started \w+ \(pid (\d+)\)", output):
        with pytest.raises(ProcessLookupError):
            os.kill(int(pid), 0)        # every child was stopped


def test_launch_names_a_node_that_dies(tmp_path, domain_id):
    lines: list = []
    proc = _launch(tmp_path, domain_id, "killed", _launcher_env())
    try:
        pump = _read_lines(proc, lines)
        deadline = time.monotonic() + 60
        body_pid = None
        while body_pid is None and time.monotonic() < deadline:
            found = re.search(r"started body \(pid (\d+)\)", "".join(lines))
            body_pid = int(found.group(1)) if found else None
            time.sleep(0.1)
        assert body_pid is not None, "".join(lines)
        while "started representation" not in "".join(lines) and time.monotonic() < deadline:
            time.sleep(0.1)
        os.kill(body_pid, signal.SIGKILL)
        proc.wait(timeout=60)
        pump.join(timeout=5)
    finally:
        _stop(proc)
    output = "".join(lines)
    assert proc.returncode != 0
    assert "node 'body' died" in output, output
    for pid in re.findall(r"started \w+ \(pid (\d+)\)", output):
        with pytest.raises(ProcessLookupError):
            os.kill(int(pid), 0)
