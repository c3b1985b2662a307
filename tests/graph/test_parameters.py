"""Invalid parameters stop a node at start-up: its name, the reason, non-zero, no traceback."""
import subprocess
import sys

import pytest

from shared import SMOKE


@pytest.mark.parametrize("node, override, name", [
    ("body", "world.grid_count:=1", "world.grid_count"),
    ("environment", "world.redistribution_probability:=1.5", "world.redistribution_probability"),
    ("agent", "pov.n_sampels:=3", "pov.n_sampels"),
    ("representation", "graph.results_dirr:=x", "graph.results_dirr"),
    ("body", "graph.executor:=multi_threaded", "graph.executor: must be one of"),
    ("environment", "graph.resend_period_s:=0.0",
     "graph.resend_period_s: must be a finite number > 0.0, got 0.0"),
    ("agent", "naive.lm_max_step:=0.0", "naive.lm_max_step: must be a finite number > 0.0, got 0.0"),
    ("agent", "naive.lm_restart:=3", "naive.lm_restart: unknown parameter"),
    ("representation", "naive.remember_sensations:=1",
     "naive.remember_sensations: must be true or false, got 1"),
    # the recorder's own parameters are schema entries too (parameters.yaml recorder.*)
    ("recorder", "recorder.chunk_interval_s:=0.0",
     "recorder.chunk_interval_s: must be a finite number > 0.0, got 0.0"),
    ("recorder", "recorder.write_ahead:=1", "recorder.write_ahead: must be true or false"),
    ("recorder", "recorder.topicz:=[/agent/done]", "recorder.topicz: unknown parameter"),
    ("replay", "match_timeout_s:=0.0", "match_timeout_s: must be a finite number > 0.0, got 0.0"),
    ("replay", "match_grace_s:=-1.0", "match_grace_s: must be a finite number >= 0.0, got -1.0"),
    # only the simulated body checks the start against the simulated arm
    ("body", "arm.initial_motor_state:=[0.1,0.2]",
     "arm.initial_motor_state: must hold one value per joint (4: 3 links"),
])
def test_invalid_parameter_stops_node_with_its_name(node, override, name, node_env, tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", f"sensorispace_ros.graph.nodes.{node}", "--ros-args",
         "--params-file", str(SMOKE), "-p", override],
        env=node_env, capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert done.returncode != 0
    assert name in done.stderr
    assert "Traceback" not in done.stderr + done.stdout


def test_a_start_of_another_body_is_not_checked_against_the_simulated_arm(context):
    """A body of one's own of 2 joints: the agent, the environment and the
    representation take a start of 2 values (the agent checks it against the
    body's description); the simulated body refuses it."""
    from sensorispace_ros import config
    from sensorispace_ros.graph import in_process
    from sensorispace_ros.graph.nodes.body import BodyNode
    from sensorispace_ros.graph.nodes.environment import EnvironmentNode

    overrides = in_process.parameter_overrides(SMOKE, {"arm.initial_motor_state": [0.5, 1.0]})
    environment = EnvironmentNode(context=context, parameter_overrides=overrides)
    try:
        assert environment.cfg["arm"]["initial_motor_state"] == [0.5, 1.0]
        assert environment.n_changes > 0
    finally:
        environment.destroy_node()
    with pytest.raises(config.ConfigError, match="arm.initial_motor_state"):
        BodyNode(context=context, parameter_overrides=overrides)
