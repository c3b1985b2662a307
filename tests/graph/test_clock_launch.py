"""`sensorispace launch` in a world on its own clock reports what the agent
found, as an offline run does: the agent's snapshot of the run over and the
body's record of time (``graph.checkpoint_dir``, which the launcher sets)
are joined by ``evaluation.graph_clock.clocked_numbers``. On the row clock
every ``naive.*`` number of the recorded run equals the offline run's
(``core.clocked_run.run_on_clock``); on the wall clock the run ends by itself
and reports its coverage and its detections, its body or its environment
killed with SIGKILL and respawned (the undisturbed wall-clock graph:
tests/graph/test_clock_graph.py).
"""
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from sensorispace_ros import config
from sensorispace_ros.evaluation import run_files
from sensorispace_ros.protocol import CHECKPOINTS, PROGRESS_FILE
from sensorispace_ros.state.environment_record import read_progress

from shared import REPO, SMOKE, SMOKE_ROW_CLOCK, SMOKE_WALL_CLOCK, stop_by_pid

pytestmark = [pytest.mark.graph, pytest.mark.slow]

# Killed and respawned mid-run, on the 12 x 12 grid: about 25 s of world, and what the
# tests ask of it (detections, an end, a resumed schedule) does not need more.
WALL = {**SMOKE_WALL_CLOCK, "world.grid_count": 12}
# Metrics that time the run, not what it did.
TIMED = ("timings", "seconds", "_s")


def _launched(tmp_path, domain_id, overrides, record, kill_after_s=None, node="body"):
    """``sensorispace launch`` of the smoke world with ``overrides``; with
    ``kill_after_s`` the process of ``node`` is killed (SIGKILL) that long
    after it started, and respawned by the launcher."""
    cfg = config.load_config(SMOKE, overrides=overrides)
    path = tmp_path / "clock.yaml"
    path.write_text(config.to_parameter_file(cfg))
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               PYTHONPATH=os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH"))
                                          if p))
    command = [sys.executable, "-m", "sensorispace_ros.cli", "launch", "--config", str(path),
               "--run", "clock", "--domain-id", str(domain_id),
               "--results", str(tmp_path / "results"), "--timeout", "400"]
    command += ([] if record else ["--no-record"]) + \
        ([] if kill_after_s is None else ["--respawn", "1"])
    proc = subprocess.Popen(command, cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        if kill_after_s is None:
            output, _ = proc.communicate(timeout=450)
        else:
            output = _kill(proc, node, kill_after_s, tmp_path / "results" / "clock" /
                           CHECKPOINTS / PROGRESS_FILE)
    finally:
        stop_by_pid(proc)
    assert proc.returncode == 0, output[-3000:]
    metrics = run_files.flatten_metrics(json.loads(
        (tmp_path / "results" / "clock" / "metrics.json").read_text()))
    return cfg, metrics, output


def _kill(proc, node: str, after_s: float, progress: Path) -> str:
    """The launcher's output, its ``node`` process killed ``after_s`` after it started,
    or, for the environment, ``after_s`` after its ``progress`` record shows a change
    played (on a slow machine its start alone may take longer than ``after_s``)."""
    lines, killed = [], False
    timer = threading.Timer(450, proc.kill)
    timer.start()
    try:
        for line in proc.stdout:
            lines.append(line)
            started = re.match(rf"\[launch\] started {node} \(pid (\d+)\)", line)
            if started and not killed:
                played = progress if node == "environment" else None
                threading.Thread(target=_kill_after, args=(int(started[1]), after_s, played),
                                 daemon=True).start()
                killed = True
        proc.wait()
    finally:
        timer.cancel()
    return "".join(lines)


def _kill_after(pid: int, after_s: float, played: Path | None) -> None:
    """SIGKILL ``pid`` ``after_s`` from now or, with ``played``, from when that
    progress record first shows a change played."""
    deadline = time.monotonic() + 300
    while played is not None and time.monotonic() < deadline:
        record = read_progress(played)
        if record is not None and record[0] >= 1:
            break
        time.sleep(0.1)
    time.sleep(after_s)
    _sigkill(pid)


def _sigkill(pid: int) -> None:
    """SIGKILL ``pid``; a graph that already stopped (its failure is what the test reports)
    has no such process."""
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def test_a_launched_run_on_the_row_clock_reports_the_offline_naive_numbers(tmp_path, domain_id):
    from sensorispace_ros.core.clocked_run import run_on_clock
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.run_world import run_world
    from sensorispace_ros.evaluation.clock import clock_metrics
    from sensorispace_ros.evaluation.naive import evaluate_naive_run

    cfg, launched, output = _launched(tmp_path, domain_id, SMOKE_ROW_CLOCK, record=True)
    assert (tmp_path / "bags" / "clock" / "metadata.yaml").is_file()    # evaluated from its bag
    assert "[launch] row " in output                                    # progress on this clock
    world = run_world(cfg)
    offline = run_on_clock(world, NaiveParams(**cfg["naive"]), "rows",
                           interval=cfg["world"]["change_interval"])
    # Rounded as metrics.json writes them.
    expected = {key: run_files.as_written(value) for key, value in {
        **evaluate_naive_run(offline, world).metrics, **clock_metrics(offline, world)}.items()
        if key.startswith("naive.") and not any(t in key for t in TIMED)}
    assert len(expected) > 40 and "naive.clock.recall" in expected
    assert {key: launched.get(key) for key in expected} == expected
    assert launched["analysis.naive_records"].startswith("world.clock: the agent's snapshot")


def test_a_launched_run_on_the_wall_clock_whose_body_is_killed_ends_and_reports(
        tmp_path, domain_id):
    _, launched, output = _launched(tmp_path, domain_id, WALL, record=False, kill_after_s=8.0)
    assert "body was killed by signal 9; respawned" in output, output[-3000:]
    logs = "".join(p.read_text() for p in (tmp_path / "results" / "clock" / "logs").iterdir())
    assert "restarted on the wall clock" in logs
    # The restarted body read back the dead one's record of time: the run is evaluated.
    assert launched["analysis.naive_records"].startswith("world.clock: the agent's snapshot")
    # Measured, not reproducible: how much the agent finds between changes every 0.15 s
    # depends on the machine's load (none at all on a loaded one); it reports it.
    assert 0.0 <= launched["naive.coverage"] <= 1.0
    assert launched["naive.distinct_positions"] <= launched["pov.count"]
    assert launched["naive.clock.detections"] > 0 and launched["naive.clock.tests"] > 0
    assert 0.0 <= launched["naive.clock.recall"] <= 1.0
    assert launched["naive.accepted_across_change"] == 0
    print({key: launched[key] for key in ("pov.count", "naive.coverage", "naive.clock.recall",
                                          "naive.clock.false_detection_rate",
                                          "naive.clock.detections")},
          re.findall(r"hold/\d+ sent again", logs))


def test_a_launched_run_on_the_wall_clock_whose_environment_is_killed_goes_on_and_ends(
        tmp_path, domain_id):
    _, launched, output = _launched(tmp_path, domain_id, WALL, record=False, kill_after_s=1.0,
                                    node="environment")
    assert "environment was killed by signal 9; respawned" in output, output[-3000:]
    logs = "".join(p.read_text() for p in (tmp_path / "results" / "clock" / "logs").iterdir())
    resumed = re.findall(r"restarted: resuming at change (\d+)", logs)
    assert len(resumed) == 1, logs[-3000:]
    # The world went on from where the dead node left it, to the end of its schedule.
    assert f"world.clock wall: {launched['naive.clock.changes']} changes played" in logs
    assert 0 < int(resumed[0]) < launched["naive.clock.changes"]
    assert launched["naive.clock.tests"] > 0 and launched["naive.accepted_across_change"] == 0
    print(resumed, {key: launched[key] for key in ("pov.count", "naive.coverage",
                                                   "naive.clock.recall", "naive.clock.detections")})
