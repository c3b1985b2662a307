"""What every test folder shares. Graphs discover on localhost only, each test
in a domain of its own (``domain_id``); processes are stopped by PID with one
grace period (``shared.stop_by_pid``); the offline naive run of
config/smoke.yaml, the reference many tests compare with, runs once per
session (``smoke_naive_reference``, ``smoke_naive_run``). Plain helpers
(``REPO``, ``SMOKE``, ``free_port``, ``stop_by_pid``) live in ``shared``,
importable from every folder."""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from shared import REPO, SMOKE, free_domain_id, free_port, stop_by_pid

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

__all__ = ["REPO", "SMOKE", "free_domain_id", "free_port", "stop_by_pid"]


@pytest.fixture
def domain_id() -> int:
    """A ROS domain id no other graph on this host uses now."""
    return free_domain_id()


@pytest.fixture
def ros_env(monkeypatch, domain_id) -> dict:
    """This test's process and children: LOCALHOST discovery in ``domain_id``;
    ``env`` for a child process that imports the package from the source tree."""
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain_id))
    monkeypatch.delenv("ROS_STATIC_PEERS", raising=False)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH")) if p)
    return {"domain_id": domain_id, "env": env}


@pytest.fixture(scope="session")
def smoke_naive_reference(tmp_path_factory) -> SimpleNamespace:
    """``sensorispace reproduce --strategy naive`` of config/smoke.yaml, seed 0,
    no figures: ``run_dir`` and its ``metrics`` (flat, dotted keys)."""
    from sensorispace_ros import config
    from sensorispace_ros.evaluation import reproduce, run_files

    run_dir = tmp_path_factory.mktemp("smoke_naive_reference")
    reproduce.reproduce(config.load_config(SMOKE), "naive", out_dir=run_dir, figures=False)
    metrics = json.loads((run_dir / run_files.METRICS_FILE).read_text())
    return SimpleNamespace(run_dir=run_dir, metrics=run_files.flatten_metrics(metrics))


@pytest.fixture(scope="session")
def smoke_naive_run():
    """The naive agent's offline run on config/smoke.yaml's world
    (``core.naive.run.run_naive``): its POVs, equality sets and agent."""
    from sensorispace_ros import config
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.naive.run import run_naive
    from sensorispace_ros.core.run_world import run_world

    cfg = config.load_config(SMOKE)
    return run_naive(run_world(cfg), NaiveParams(**cfg["naive"]))


def pytest_collection_modifyitems(config, items):
    """Files with graph tests first, then files with slow tests, then the rest,
    each file's tests in their own order: the workers of ``scripts/test.sh``
    (pytest-xdist, a file per worker at a time) start on the long files and
    end on short ones, instead of one worker finishing a long file alone."""
    def weight(item) -> int:
        return 0 if item.get_closest_marker("graph") else 1 if item.get_closest_marker("slow") \
            else 2

    files: dict = {}
    for item in items:
        files[item.path] = min(files.get(item.path, 2), weight(item))
    items.sort(key=lambda item: files[item.path])
