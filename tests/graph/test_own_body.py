"""A body of one's own (docs/own-body.md): examples/own_body.py, a two-joint
arm in degrees with three receptors, written with rclpy and sensor_msgs
alone, in place of the project's simulator, run by the doc's commands with
the project's environment, agent and representation, each a process of its
own on a private domain, on config/smoke.yaml. Given a start of two values,
or none (every joint at 0: a straight arm, singular, which the agent leaves
by itself), every process exits by itself, the agent finds points of view
and the representation is written in a run directory of its own. Publishing
UINT16 counts (a 16-bit sensor), the run goes to its end as well. In a
world of its own that changes on its own (``--own-world``, the agent's
``world.clock: wall``), the body runs with the agent and the representation
and no environment node: no lights message, and the run ends by itself."""
from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from shared import REPO, SMOKE, stop_by_pid

pytestmark = [pytest.mark.graph, pytest.mark.slow]

OWN_BODY = REPO / "examples" / "own_body.py"
NODES = ("agent", "representation", "environment")


def run_own_body(tmp_path: Path, domain_id: int, extra: list[str], body_args=(),
                 nodes=NODES) -> dict:
    """The doc's commands; returns each process's exit code and log, once all have exited."""
    from sensorispace_ros.graph.dds_environment import graph_environment

    env = graph_environment(domain_id)            # this test's domain, localhost only
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    env["PYTHONPATH"] = str(REPO)
    params = ["--ros-args", "--params-file", str(SMOKE), "-p",
              f"graph.results_dir:={tmp_path / 'results' / '{run}'}", *extra]
    commands = {"own_body": [str(OWN_BODY), *body_args],
                **{name: ["-m", f"sensorispace_ros.graph.nodes.{name}", *params]
                   for name in nodes}}
    if "environment" in commands:
        commands["environment"] += ["-p", "graph.wait_for_nodes:=[own_body,agent,representation]"]
    processes, logs = {}, {name: tmp_path / f"{name}.log" for name in commands}
    try:
        for name, command in commands.items():
            with open(logs[name], "wb") as log:
                processes[name] = subprocess.Popen(
                    [sys.executable, *command], env=env, stdout=log, stderr=subprocess.STDOUT,
                    cwd=tmp_path, start_new_session=True)
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and any(p.poll() is None for p in processes.values()):
            time.sleep(0.2)
        running = [name for name, p in processes.items() if p.poll() is None]
    finally:
        for process in processes.values():
            stop_by_pid(process)
    return {"running": running, "codes": {n: p.returncode for n, p in processes.items()},
            "logs": {name: path.read_text() for name, path in logs.items()}}


def check_run(tmp_path: Path, run: dict) -> str:
    logs = run["logs"]
    assert not run["running"], (run["running"], logs["agent"][-3000:])
    assert set(run["codes"].values()) == {0}, (run["codes"], logs["agent"][-3000:])
    assert "body: 2 joints (hip, knee) in deg, 3 receptors" in logs["agent"]
    assert "measured body: pose rank 2 of 2 joints" in logs["agent"], logs["agent"][-3000:]
    found = re.search(r"run over: found (\d+) points of view", logs["agent"])
    assert found and int(found.group(1)) > 20, logs["agent"][-3000:]
    assert not re.search(r"dropped a message|Traceback", logs["agent"]), logs["agent"][-3000:]
    [written] = (tmp_path / "results").glob("run-*/representation.npz")
    assert f"representation written to {written}" in logs["representation"]
    with np.load(written) as stored:
        assert "reason" not in stored
        assert len(stored["pov_ids"]) == int(found.group(1))
        assert stored["povs"].shape[2] == 2 and "embedding_2d_before" in stored
    assert (written.parent / "agent_records.npz").is_file()
    return logs["agent"]


def test_an_own_body_with_its_own_start(tmp_path, domain_id):
    run = run_own_body(tmp_path, domain_id, ["-p", "arm.initial_motor_state:=[30.0,60.0]"])
    agent_log = check_run(tmp_path, run)
    assert "start kept" not in agent_log and "instead" not in agent_log


def test_an_own_body_with_the_default_start_which_is_straight(tmp_path, domain_id):
    run = run_own_body(tmp_path, domain_id, [])
    agent_log = check_run(tmp_path, run)
    # smoke.yaml's start is the simulated arm's (4 values): every joint at 0, a
    # straight arm whose rank the agent measures as lower than elsewhere.
    assert "starting with every joint at 0" in agent_log
    assert re.search(r"the given start has pose rank 1, 2 is measured elsewhere .*"
                     r"started at a state of rank 2 instead", agent_log), agent_log[-3000:]


def test_an_own_body_publishing_uint16_counts_runs_to_the_end(tmp_path, domain_id):
    """The body publishing what a 16-bit ADC gives: the agent reads every
    sensation (none dropped), every process exits by itself, and the
    representation writes its result or the reason it has none."""
    run = run_own_body(tmp_path, domain_id, ["-p", "arm.initial_motor_state:=[30.0,60.0]"],
                       body_args=("--sensor-type", "uint16"))
    logs = run["logs"]
    assert not run["running"], (run["running"], logs["agent"][-3000:])
    assert set(run["codes"].values()) == {0}, (run["codes"], logs["agent"][-3000:])
    assert "body: 2 joints (hip, knee) in deg, 3 receptors" in logs["agent"]
    assert not re.search(r"dropped a message|Traceback", logs["agent"]), logs["agent"][-3000:]
    found = re.search(r"run over: found (\d+) points of view", logs["agent"])
    assert found, logs["agent"][-3000:]
    [written] = (tmp_path / "results").glob("run-*/representation.npz")
    with np.load(written) as stored:
        assert len(stored["pov_ids"]) == int(found.group(1))
        assert ("reason" in stored) == (int(found.group(1)) < 4)
    print(f"the agent on the UINT16 body: {found.group(0)}")


def test_sensorispace_launch_no_body_runs_with_the_own_body(tmp_path, domain_id):
    """``sensorispace launch --no-body``: the project's nodes without the
    simulated body, the user's body started beside; the run ends, it is not
    evaluated, and the representation is in the run's directory."""
    from sensorispace_ros.graph.dds_environment import graph_environment

    env = graph_environment(domain_id)
    env["PYTHONPATH"] = str(REPO)
    launch = [sys.executable, "-m", "sensorispace_ros.cli", "launch", "--config", str(SMOKE),
              "--no-body", "--no-record", "--run", "own", "--domain-id", str(domain_id),
              "--results", str(tmp_path / "results"), "--timeout", "300"]
    processes = {}
    try:
        with open(tmp_path / "own_body.log", "wb") as log:
            processes["own_body"] = subprocess.Popen(
                [sys.executable, str(OWN_BODY)], env=env, stdout=log,
                stderr=subprocess.STDOUT, cwd=tmp_path, start_new_session=True)
        processes["launch"] = subprocess.Popen(launch, env=env, stdout=subprocess.PIPE,
                                               stderr=subprocess.STDOUT, text=True, cwd=tmp_path,
                                               start_new_session=True)
        output, _ = processes["launch"].communicate(timeout=360)
        processes["own_body"].wait(timeout=30)
    finally:
        for process in processes.values():
            stop_by_pid(process)
    assert processes["launch"].returncode == 0, output[-3000:]
    assert processes["own_body"].returncode == 0
    assert "started body" not in output and "not evaluated" in output, output[-3000:]
    results = tmp_path / "results" / "own"
    with np.load(results / "representation.npz") as stored:
        assert stored["povs"].shape[2] == 2 and len(stored["pov_ids"]) > 20
    assert not (results / "logs" / "body.log").exists()


def test_an_own_body_in_a_world_that_changes_on_its_own(tmp_path, domain_id):
    """docs/own-body.md, "A body in a physical world": the agent and the
    representation, no environment node; the body's world changes on
    its own 100 times, every 0.3 s on average, whatever the agent does. The agent
    finds points of view, tells changes it was never told of, and the run
    ends when the body's world has no change left."""
    run = run_own_body(tmp_path, domain_id,
                       ["-p", "arm.initial_motor_state:=[30.0,60.0]", "-p", "world.clock:=wall"],
                       body_args=("--own-world", "100", "--change-period", "0.3"),
                       nodes=("agent", "representation"))
    logs = run["logs"]
    assert "/environment/lights" not in logs["own_body"]
    check_run(tmp_path, run)
    told = re.search(r"(\d+) reactions kept, .* (\d+) changes flagged in (\d+) tests",
                     logs["agent"])
    assert told and int(told.group(1)) > 0 and int(told.group(2)) > 0, logs["agent"][-3000:]
    print(told.group(0))
