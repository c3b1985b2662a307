"""The bag tests' graphs: a private rclpy Context in the test's domain
(``ros_env``, tests/conftest.py), child processes stopped by PID."""
from __future__ import annotations

import subprocess
import sys

import pytest
from shared import REPO, stop_by_pid


@pytest.fixture
def ros_context(ros_env):
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context, domain_id=ros_env["domain_id"])
    yield context
    context.try_shutdown()


@pytest.fixture
def children():
    """Start child processes; every one still alive at the end is stopped by PID."""
    started: list[subprocess.Popen] = []

    def start(args, env, **kwargs):
        process = subprocess.Popen([sys.executable, *args], env=env, cwd=REPO,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                   text=True, **kwargs)
        started.append(process)
        return process

    yield start
    for process in started:
        stop_by_pid(process)
