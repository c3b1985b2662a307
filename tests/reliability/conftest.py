"""Reliability tests: every graph discovers on localhost only, in a
domain of its own, and every process a test starts is stopped by PID."""
from __future__ import annotations

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


@pytest.fixture(scope="session")
def single_host_result(tmp_path_factory):
    """The smoke run with every node in this process (the reference result).

    tests/ros/test_graph_in_process.py shows this equals the offline naive run.
    """
    from sensorispace_ros.graph.dds_environment import free_domain_id
    from sensorispace_ros.graph.in_process import run_graph_in_process

    from .node_processes import load_result
    results = tmp_path_factory.mktemp("single_host")
    run = run_graph_in_process(SMOKE, free_domain_id(), results, timeout_s=400)
    reference = load_result(results)
    reference["wall_s"] = run["wall_s"]
    return reference
