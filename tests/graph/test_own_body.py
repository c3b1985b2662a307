"""A body of one's own (docs/own-body.md): tests/graph/own_body.py, two joints in
degrees and three receptors, written with rclpy and sensor_msgs alone, in
place of the project's simulator. The project's environment and agent, each
a process of its own on a private domain, take it as it describes itself: the
agent sends 2-column commands, gets 3-column sensations, settles change
after change and ends the run with its totals. It need not find any spatial
structure in such a body."""
from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from shared import SMOKE, stop_by_pid

pytestmark = [pytest.mark.graph, pytest.mark.slow]

OWN_BODY = Path(__file__).resolve().parent / "own_body.py"


class Observer:
    """A participant of the test's own: the fields of every command and
    sensation, the changes the agent settled and its /agent/done totals."""

    def __init__(self, domain_id: int):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        from sensor_msgs.msg import PointCloud2
        from std_msgs.msg import UInt64

        from sensorispace_ros import contracts

        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("own_body_observer", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.fields = {"/body/motor_command": set(), "/body/sensation": set()}
        self.datatypes = {topic: set() for topic in self.fields}      # PointField datatypes
        self.settled: list[int] = []
        self.done: dict | None = None
        for topic, seen in self.fields.items():
            self.node.create_subscription(
                PointCloud2, topic,
                lambda msg, seen=seen, types=self.datatypes[topic]: (
                    seen.add(tuple(f.name for f in msg.fields)),
                    types.update(f.datatype for f in msg.fields)),
                contracts.subscription_qos(topic))
        self.node.create_subscription(UInt64, "/agent/settled",
                                      lambda msg: self.settled.append(msg.data),
                                      contracts.subscription_qos("/agent/settled"))
        self.node.create_subscription(PointCloud2, "/agent/done", self.on_done,
                                      contracts.subscription_qos("/agent/done"))

    def on_done(self, msg) -> None:
        from sensorispace_ros import contracts, messages

        table = messages.cloud_to_table(msg, contracts.contract("/agent/done").columns)
        self.done = {name: int(table[name][0]) for name in table.dtype.names}

    def spin_until(self, done, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while not done() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


def _run(tmp_path, domain_id, body_options=(), representation=False):
    """The own body, the project's agent and environment (and representation),
    each a process; returns the observer, the logs' text and the processes
    that exited before the observer saw the end (and, with the representation,
    before that wrote its result or said why not)."""
    from sensorispace_ros.graph.dds_environment import graph_environment

    env = graph_environment(domain_id)            # this test's domain, localhost only
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[2])
    graph = ["-p", f"graph.results_dir:={tmp_path / 'results'}"]
    commands = {
        "own_body": [str(OWN_BODY), *body_options],
        "agent": ["-m", "sensorispace_ros.graph.nodes.agent", "--ros-args",
                  "--params-file", str(SMOKE), *graph],
        "environment": ["-m", "sensorispace_ros.graph.nodes.environment", "--ros-args",
                        "--params-file", str(SMOKE), *graph,
                        "-p", "graph.wait_for_nodes:=[own_body,agent]"]}
    if representation:
        commands["representation"] = ["-m", "sensorispace_ros.graph.nodes.representation",
                                      "--ros-args", "--params-file", str(SMOKE), *graph]
    processes, logs = {}, {name: tmp_path / f"{name}.log" for name in commands}
    observer = Observer(domain_id)

    def ended():
        if representation:
            return processes["representation"].poll() is not None or observer.done is not None \
                and re.search(r"representation (written|failed)", logs["representation"].read_text())
        return observer.done is not None or any(p.poll() is not None for p in processes.values())
    try:
        for name, command in commands.items():
            with open(logs[name], "wb") as log:
                processes[name] = subprocess.Popen(
                    [sys.executable, *command], env=env, stdout=log, stderr=subprocess.STDOUT,
                    start_new_session=True)
        observer.spin_until(ended, timeout_s=240)
        exited = {name: p.returncode for name, p in processes.items() if p.poll() is not None}
    finally:
        observer.close()
        for process in processes.values():
            stop_by_pid(process)
    return observer, {name: path.read_text() for name, path in logs.items()}, exited, processes


def test_the_agent_sizes_itself_from_a_body_it_does_not_know(tmp_path, domain_id):
    observer, logs, exited, processes = _run(tmp_path, domain_id)
    agent_log = logs["agent"]
    assert not exited, (exited, agent_log[-3000:])
    assert observer.done is not None, agent_log[-3000:]
    n_changes = int(re.search(r"(\d+) environmental changes scheduled",
                              logs["environment"]).group(1))
    # Every change was settled (the observer may join late: the last ones at
    # least), and the end came through the body's passive sensation.
    assert observer.done["changes"] == n_changes + 1 and observer.done["calls"] > 0
    assert len(set(observer.settled)) > 1 and max(observer.settled) >= n_changes
    assert "body: 2 joints (hip, knee) in deg, 3 receptors" in agent_log
    assert observer.fields["/body/motor_command"] == {("m0", "m1")}
    assert observer.fields["/body/sensation"] == {("s0", "s1", "s2")}
    assert not re.search(r"dropped a message", agent_log), agent_log[-3000:]
    assert all(process.poll() is not None for process in processes.values())


def test_the_agent_takes_the_uint16_sensations_of_a_16_bit_sensor(tmp_path, domain_id):
    """The own body publishing what a 16-bit ADC gives (UINT16 columns): the
    agent reads them (as float64, none dropped), the run ends, and the
    representation writes its result or says why it has none."""
    from sensor_msgs.msg import PointField

    observer, logs, exited, _ = _run(tmp_path, domain_id, ("--sensor-type", "uint16"),
                                     representation=True)
    agent_log = logs["agent"]
    assert observer.datatypes["/body/sensation"] == {PointField.UINT16}
    assert observer.done is not None, agent_log[-3000:]
    assert not exited.keys() - {"representation"}, (exited, agent_log[-3000:])
    n_changes = int(re.search(r"(\d+) environmental changes scheduled",
                              logs["environment"]).group(1))
    assert observer.done["changes"] == n_changes + 1 and observer.done["calls"] > 0
    assert "body: 2 joints (hip, knee) in deg, 3 receptors" in agent_log
    assert not re.search(r"dropped a message", agent_log), agent_log[-3000:]
    written = (tmp_path / "results" / "representation.npz").is_file()
    said_why = re.search(r"representation failed: (.+)|no representation: (.+)",
                         logs["representation"])
    assert written or said_why, logs["representation"][-3000:]
    print(f"the agent on the UINT16 body: {observer.done}; representation "
          + ("written" if written else f"not written: {said_why.group(0)}"))
