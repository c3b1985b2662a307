"""(b) `sensorispace launch`: one process per node, a run to completion, a killed node named.

Also (c) on the multi-process graph: the live graph, read from another
participant, shows the agent subscribing only to /body/sensation and the
body's description, the representation only to /agent/* and the description. And parity with the offline run: the launched smoke
run's metrics.json (evaluated from its bag by ``sensorispace analyze``) has
every key of ``sensorispace reproduce --strategy naive`` and the same numbers.
"""
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time

import pytest
import rclpy
from rclpy.context import Context
from rclpy.signals import SignalHandlerOptions

from shared import REPO, SMOKE, stop_by_pid

pytestmark = [pytest.mark.graph, pytest.mark.slow]


def _launch(tmp_path, domain_id, run, env, record=False):
    command = [sys.executable, "-m", "sensorispace_ros.cli", "launch", "--config", str(SMOKE),
               "--run", run, "--domain-id", str(domain_id),
               "--results", str(tmp_path / "results"), "--timeout", "400"]
    if not record:
        command.append("--no-record")
    return subprocess.Popen(command, cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)


def _read_lines(proc, lines: list) -> threading.Thread:
    def pump():
        for line in proc.stdout:
            lines.append(line)
    thread = threading.Thread(target=pump, daemon=True)
    thread.start()
    return thread


def _launcher_env():
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH")) if p)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    return env


def _subscriptions_of(domain_id: int, names, deadline_s: float = 60.0) -> dict:
    """Topics each node subscribes to, read from the live graph by another participant."""
    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("naivety_observer", context=context)
    try:
        deadline = time.monotonic() + deadline_s
        seen = {}
        while time.monotonic() < deadline:
            present = set(node.get_node_names())
            if all(n in present for n in names):
                seen = {n: sorted(t for t, _ in node.get_subscriber_names_and_types_by_node(n, "/"))
                        for n in names}
                if all(seen.values()):
                    return seen
            time.sleep(0.2)
        return seen
    finally:
        node.destroy_node()
        context.try_shutdown()


@pytest.fixture(scope="module")
def smoke_launch(tmp_path_factory):
    """One recorded `sensorispace launch` of the smoke config for the module."""
    from shared import free_domain_id

    tmp_path, domain_id = tmp_path_factory.mktemp("launch"), free_domain_id()
    lines: list = []
    proc = _launch(tmp_path, domain_id, "smoke", _launcher_env(), record=True)
    try:
        pump = _read_lines(proc, lines)
        seen = _subscriptions_of(domain_id, ("agent", "representation", "body"))
        proc.wait(timeout=450)
        pump.join(timeout=5)
    finally:
        stop_by_pid(proc)
    return {"output": "".join(lines), "returncode": proc.returncode, "seen": seen,
            "domain_id": domain_id, "results": tmp_path / "results" / "smoke"}


def test_launch_runs_the_smoke_config_and_the_agent_is_naive(smoke_launch):
    output, seen, domain_id = (smoke_launch[k] for k in ("output", "seen", "domain_id"))
    assert smoke_launch["returncode"] == 0, output
    assert f"ROS_DOMAIN_ID={domain_id}" in output and "LOCALHOST" in output
    # progress from the environment's record (the launcher is not in the graph)
    assert re.search(r"^\[launch\] change \d+/\d+ \(\d+ %\) after ", output, re.M), output
    assert seen.get("agent") == ["/body/description", "/body/sensation"], seen
    assert "/body/description" in seen.get("representation", []) and all(
        t.startswith("/agent/") for t in seen["representation"] if t != "/body/description"), seen
    assert "/environment/lights" in seen.get("body", [])
    metrics = json.loads((smoke_launch["results"] / "metrics.json").read_text())
    # The agent's own counters made it through /agent/done to the evaluator.
    assert metrics["pov"]["count"] == metrics["agent"]["points_of_view"] > 3
    assert metrics["exploration"]["compensated"] == metrics["agent"]["compensated"] > 0
    assert "after" in metrics["quality"]["2d"]
    # The snapshot's wait for its reactions to be acknowledged ends with the
    # acknowledgements (the graph's writers heartbeat every 100 ms), not at its 1 s timeout.
    transport = [line for line in (smoke_launch["results"] / "logs" / "agent.log").read_text()
                 .splitlines() if "transport:" in line]
    assert transport and re.search(r"\b[1-9]\d* snapshots", transport[0]), transport
    assert " 0 acknowledgement waits timed out" in transport[0], transport
    # Every probe message took CloudCdrReader's fast path both ways (between
    # processes the payloads arrive padded; the general path read them all once).
    assert transport[0].endswith(" 0 sensations not read by the fast path"), transport
    # The recorder said it held the agent's whole run before the launcher stopped
    # it (recording.completeness), and took its marker away with the bag closed.
    recorder_log = (smoke_launch["results"] / "logs" / "recorder.log").read_text()
    assert "holds the agent's whole run (smoke.complete)" in recorder_log, recorder_log[-2000:]
    assert "does not hold the agent's whole run" not in output
    bag = smoke_launch["results"].parent.parent / "bags" / "smoke"
    assert (bag / "metadata.yaml").is_file() and not (bag.parent / "smoke.complete").exists()
    body_log = (smoke_launch["results"] / "logs" / "body.log").read_text()
    assert re.search(r"answered [1-9]\d* commands, 0 not read by the fast path", body_log), \
        body_log[-2000:]
    for pid in re.findall(r"started \w+ \(pid (\d+)\)", output):
        with pytest.raises(ProcessLookupError):
            os.kill(int(pid), 0)        # every child was stopped


# Graph and offline: equal for the same seed and config (counts exactly, numbers within 1e-6).
PARITY_PREFIXES = ("exploration.", "quality.")
PARITY_KEYS = ("pov.count", "naive.coverage", "naive.wrong_poses", "naive.state_changes_accepted")


@pytest.fixture(scope="module")
def unrecorded_launch(tmp_path_factory):
    """One `sensorispace launch --no-record` of the smoke config: evaluated without a bag."""
    from shared import free_domain_id

    tmp_path = tmp_path_factory.mktemp("launch_no_record")
    proc = _launch(tmp_path, free_domain_id(), "smoke", _launcher_env(), record=False)
    try:
        output, _ = proc.communicate(timeout=450)
    finally:
        stop_by_pid(proc)
    return {"output": output, "returncode": proc.returncode,
            "results": tmp_path / "results" / "smoke"}


@pytest.mark.parametrize("launched, evaluated_from", [("smoke_launch", "the bag"),
                                                      ("unrecorded_launch", "agent_records.npz")])
def test_launched_metrics_have_the_offline_naive_keys_and_numbers(launched, evaluated_from,
                                                                   smoke_naive_reference, request):
    from sensorispace_ros.evaluation import run_files

    run = request.getfixturevalue(launched)
    assert run["returncode"] == 0, run["output"]
    graph = run_files.flatten_metrics(json.loads((run["results"] / "metrics.json").read_text()))
    assert graph["analysis.naive_records"].startswith("evaluated"), \
        f"not evaluated from {evaluated_from}: {graph['analysis.naive_records']}"
    offline = smoke_naive_reference.metrics

    def compared(key):
        return not (key.startswith(("timings_s.", "config.", "analysis."))
                    or ".timings_s." in key or ".seconds_by_stage." in key)

    missing = sorted(k for k in offline if compared(k) and k not in graph)
    assert not missing, f"keys of the offline naive metrics.json missing in the graph's: {missing}"
    checked = [k for k in offline if k in PARITY_KEYS or k.startswith(PARITY_PREFIXES)]
    assert {"exploration.compensated", "exploration.events", "exploration.state_changes",
            "quality.2d.after.affine_residual", *PARITY_KEYS} <= set(checked)
    for key in checked:
        if isinstance(offline[key], (int, float)) and not isinstance(offline[key], bool):
            assert graph[key] == pytest.approx(offline[key], abs=1e-6, rel=0), key
        else:
            assert graph[key] == offline[key], key
    assert offline["exploration.compensated"] > 0 and offline["pov.count"] > 3
    # The agent's own counters, reported both ways from the same records.
    for key in ("naive.queries_total", "naive.calls_total", "naive.queries_per_pov",
                "naive.queries_per_compensation", "naive.compensations_accepted"):
        assert graph[key] == offline[key], key


def test_launch_names_a_node_that_dies(tmp_path, domain_id):
    lines: list = []
    proc = _launch(tmp_path, domain_id, "killed", _launcher_env())
    try:
        pump = _read_lines(proc, lines)
        deadline = time.monotonic() + 60
        body_pid = None
        while body_pid is None and time.monotonic() < deadline:
            found = re.search(r"started body \(pid (\d+)\)", "".join(lines))
            body_pid = int(found.group(1)) if found else None
            time.sleep(0.1)
        assert body_pid is not None, "".join(lines)
        while "started representation" not in "".join(lines) and time.monotonic() < deadline:
            time.sleep(0.1)
        os.kill(body_pid, signal.SIGKILL)
        proc.wait(timeout=60)
        pump.join(timeout=5)
    finally:
        stop_by_pid(proc)
    output = "".join(lines)
    assert proc.returncode != 0
    assert "node 'body' died" in output, output
    for pid in re.findall(r"started \w+ \(pid (\d+)\)", output):
        with pytest.raises(ProcessLookupError):
            os.kill(int(pid), 0)
