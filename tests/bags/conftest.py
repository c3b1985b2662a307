"""ROS hygiene for the bag tests: localhost-only discovery, a domain id of its
own per test, private rclpy Contexts, child processes stopped by PID."""
from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import zlib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
_counter = itertools.count()


@pytest.fixture
def ros_env(monkeypatch, request):
    """Environment for this test's graph: LOCALHOST discovery and its own domain id."""
    # 150..229: away from the default 0 and from other suites' small ids
    domain = 150 + (zlib.crc32(request.node.nodeid.encode()) + os.getpid() + next(_counter)) % 80
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.delenv("ROS_STATIC_PEERS", raising=False)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return {"domain_id": domain, "env": env}


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
    """Start child processes; every one still alive at the end gets SIGTERM by PID."""
    started: list[subprocess.Popen] = []

    def start(args, env, **kwargs):
        process = subprocess.Popen([sys.executable, *args], env=env, cwd=REPO,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                   text=True, **kwargs)
        started.append(process)
        return process

    yield start
    for process in started:
        if process.poll() is None:
            os.kill(process.pid, signal.SIGTERM)
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.kill(process.pid, signal.SIGKILL)
                process.wait()
