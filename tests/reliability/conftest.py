"""Reliability tests (issue #7): every graph discovers on localhost only, in a
domain of its own, and every process a test starts is stopped by PID."""
from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

import pytest

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

REPO = Path(__file__).resolve().parents[2]
SMOKE = REPO / "config" / "smoke.yaml"


def stop_by_pid(process: subprocess.Popen, grace_s: float = 5.0) -> None:
    """SIGTERM, then SIGKILL after ``grace_s``; never by name."""
    if process.poll() is None:
        try:
            os.kill(process.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        try:
            process.wait(timeout=grace_s)
        except subprocess.TimeoutExpired:
            try:
                os.kill(process.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            process.wait()


@pytest.fixture
def domain_id():
    from sensorispace_ros.launcher import free_domain_id
    return free_domain_id()


@pytest.fixture(scope="session")
def single_host_result(tmp_path_factory):
    """The smoke run with every node in this process (the reference result).

    tests/ros/test_graph_in_process.py shows this equals the offline naive run.
    """
    from sensorispace_ros.launcher import free_domain_id, run_graph_in_process

    from .node_processes import load_result
    results = tmp_path_factory.mktemp("single_host")
    run = run_graph_in_process(SMOKE, free_domain_id(), results, timeout_s=400)
    reference = load_result(results)
    reference["wall_s"] = run["wall_s"]
    return reference
