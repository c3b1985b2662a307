"""The reliability tests' reference: the smoke graph with every node in one
process (``domain_id`` and stopping by PID: tests/conftest.py)."""
from __future__ import annotations

import pytest
from shared import SMOKE


@pytest.fixture(scope="session")
def single_host_result(tmp_path_factory):
    """The smoke run with every node in this process (the reference result).

    tests/graph/test_graph_in_process.py shows this equals the offline naive run.
    """
    from sensorispace_ros.graph.dds_environment import free_domain_id
    from sensorispace_ros.graph.in_process import run_graph_in_process

    from .node_processes import load_result
    results = tmp_path_factory.mktemp("single_host")
    run = run_graph_in_process(SMOKE, free_domain_id(), results, timeout_s=400)
    reference = load_result(results)
    reference["wall_s"] = run["wall_s"]
    return reference
