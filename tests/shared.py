"""Helpers every test folder shares (``tests/conftest.py`` puts this folder on
``sys.path`` and turns them into fixtures): the repository root, a free TCP
port, stopping a process by its PID, a node run as a process of its own, and
spinning an in-process graph whose agent runs in its ``step``, and a ROS
domain id of this test worker's own."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SMOKE = REPO / "config" / "smoke.yaml"
# The smoke world on the row clock, on a 12 x 12 grid: the graph makes every call of the
# offline run on it as on the 16 x 16 one, in half the time. Simulation 2 lasts until the
# world ends the run, its end answering a hold (an agent that ends simulation 2 itself tells
# the body with one row more, ``end_run``, that the offline driver does not play).
SMOKE_ROW_CLOCK = {"world.clock": "rows", "world.change_interval": 2000.0,
                   "naive.clock_equality_changes": 400, "world.grid_count": 12}
# The smoke world on the wall clock: a change every 0.15 s on average, the schedule once
# (no simulation 2), about 45 s of world on the 16 x 16 grid.
SMOKE_WALL_CLOCK = {"world.clock": "wall", "world.change_period_s": 0.15,
                    "naive.clock_equality_changes": 0}
# How long a stopped process gets to exit after SIGTERM before SIGKILL.
GRACE_S = 10.0


# Test processes run side by side (pytest-xdist, ``scripts/test.sh``): each
# worker draws its graphs' domain ids from its own band of 1..100.
_DOMAIN_BAND = 25


def free_domain_id() -> int:
    """A ROS domain id no graph on this host uses now, from this test
    worker's band (``graph.dds_environment.free_domain_id`` probes from there)."""
    from sensorispace_ros.graph.dds_environment import free_domain_id as probe

    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    band = int(worker[2:]) if worker[2:].isdigit() else 0
    return probe(start=(band * _DOMAIN_BAND + os.getpid() % _DOMAIN_BAND) % 100 + 1)


def free_port() -> int:
    """A TCP port nothing listens on now (the OS's choice)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def stop_by_pid(process: subprocess.Popen, grace_s: float = GRACE_S) -> int | None:
    """SIGTERM to ``process`` by its PID, then SIGKILL if it is still alive
    after ``grace_s``; returns its exit code (None if it never started)."""
    if process is None:
        return None
    if process.poll() is None:
        try:
            process.send_signal(signal.SIGTERM)
            process.wait(timeout=grace_s)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        except ProcessLookupError:
            pass
    return process.returncode


def count_world_builds(monkeypatch) -> dict:
    """Count, from now on, the worlds built (``core.paper.exploration.build_world``,
    what ``core.run_world.run_world`` calls) and the paper explorations run
    (``explore_paper``, the naive coverage denominator): ``{"worlds", "explorations"}``."""
    from sensorispace_ros.core.paper import exploration

    counts = {"worlds": 0, "explorations": 0}
    for name, key in (("build_world", "worlds"), ("explore_paper", "explorations")):
        original = getattr(exploration, name)

        def counted(*args, _original=original, _key=key, **kwargs):
            counts[_key] += 1
            return _original(*args, **kwargs)
        monkeypatch.setattr(exploration, name, counted)
    return counts


class NodeProcess:
    """A graph node as a child process (``command``: ``launcher.node_command``),
    killed with SIGKILL by its PID and started again with the same command
    line; each start logs to ``<log_dir>/<name>-<k>.log`` (``logs``)."""

    def __init__(self, name: str, command: list, env: dict, log_dir: Path):
        self.name, self.command, self.env, self.log_dir = name, command, env, Path(log_dir)
        self.logs: list = []
        self.process: subprocess.Popen | None = None

    def start(self) -> None:
        log = self.log_dir / f"{self.name}-{len(self.logs)}.log"
        self.logs.append(log)
        with open(log, "wb") as out:
            self.process = subprocess.Popen(self.command, env=self.env, stdout=out,
                                            stderr=subprocess.STDOUT, start_new_session=True)

    def kill9(self) -> None:
        os.kill(self.process.pid, signal.SIGKILL)
        self.process.wait()


def spin_graph(graph, seconds: float) -> None:
    """Spin ``graph`` (``in_process._InProcessGraph``) for ``seconds``, calling
    each node's ``step`` between callbacks (the agent's driver runs there)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        graph.executor.spin_once(timeout_sec=0.05)
        for node in graph.nodes.values():
            step = getattr(node, "step", None)
            if step is not None:
                step()
