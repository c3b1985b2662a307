"""A real (tiny) graph run recorded by the launcher's recorder: nothing dropped.

Published counts are not observable from outside the nodes, but the graph's
protocol ties them together: every motor command is answered by one
sensation, one sensor pose and one joint state; every change by one passive
sensation, one lights message and one settled; the agent's /agent/done
totals count its commands, points of view and equality rows. A dropped
message on any topic breaks one of these identities.
"""
from __future__ import annotations

import io
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from sensorispace_ros.evaluation import analyze
from sensorispace_ros.graph.dds_environment import free_domain_id
from sensorispace_ros.recording.bag_reader import bag_info, read_bag_messages

from shared import REPO, count_world_builds

pytestmark = pytest.mark.slow

TINY = """/**:
  ros__parameters:
    seed: 0
    world:
      grid_count: 12              # >= 11 points of view: the evaluation needs them
    pov:
      n_samples: 20
      step: 0.01
      close_tol: 0.03
    representation:
      cca:
        n_epochs: 10
      regularization:
        iterations: 2
      reaching:
        pairs: 10
        max_degree: 6
    output:
      figures: false
"""


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """One launched tiny run for the module: (bag, results dir, config file)."""
    from sensorispace_ros.graph import launcher

    root = tmp_path_factory.mktemp("graph")
    config = root / "tiny.yaml"
    config.write_text(TINY)
    log = io.StringIO()
    previous = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE")
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    try:
        result = launcher.launch_graph(config, run="tiny", domain_id=free_domain_id(),
                                       record=True, results_root=root / "results",
                                       bags_root=root / "bags", timeout_s=240, stream=log)
    finally:
        if previous is None:
            os.environ.pop("ROS_AUTOMATIC_DISCOVERY_RANGE", None)
        else:
            os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = previous
    bag = root / "bags" / "tiny"
    assert (bag / "metadata.yaml").is_file(), log.getvalue()  # closed cleanly by SIGTERM
    return {"bag": bag, "results": result.results_dir, "config": config,
            "exit_code": result.exit_code, "log": log.getvalue()}


@pytest.fixture
def recorded_tiny_run(tiny_run):
    return tiny_run["bag"]


def frames(bag, topic) -> list[str]:
    return [m.header.frame_id for _, _, _, m in read_bag_messages(bag, [topic])]


def test_graph_recording_drops_nothing(recorded_tiny_run):
    bag = recorded_tiny_run
    counts = bag_info(bag).counts
    totals = analyze.agent_totals(bag)
    assert totals is not None, counts
    changes = totals["changes"]
    # The environment re-sends a change the agent has not settled yet (graph.resend_period_s),
    # so a message may be recorded twice: the identities hold on distinct frame ids.
    commands = frames(bag, "/body/motor_command")
    # With each settle the agent sends the next change's first call (next/<k>); the
    # one sent with the last change's settle is answered after the end, never used.
    assert len(commands) == len(set(commands)) == totals["calls"] + 1
    assert f"next/{changes}" in commands
    assert sum(f.startswith("next/") for f in commands) == changes
    sensations = set(frames(bag, "/body/sensation"))
    passive = {f for f in sensations if f.startswith(("change/", "end/"))}
    assert sensations - passive == set(commands)
    assert passive == {f"change/{k}" for k in range(changes)} | {f"end/{changes}"}
    for topic in ("/body/sensor_pose", "/body/joint_states"):
        assert set(frames(bag, topic)) == sensations, topic
    assert set(frames(bag, "/environment/lights")) == passive
    assert set(frames(bag, "/environment/event")) == {f"change/{k}" for k in range(1, changes)}
    settled = [m.data for _, _, _, m in read_bag_messages(bag, ["/agent/settled"])]
    assert sorted(set(settled)) == list(range(changes + 1))
    data = analyze.agent_data(bag)
    assert len(data["ids"]) == totals["points_of_view"]
    assert data["rows_held"] == totals["compensation_rows"]
    # every POV's first motor state was commanded, and its answer recorded
    _, recorded = analyze.true_poses(bag, data["povs"])
    assert recorded == len(data["ids"])
    assert np.isfinite(data["povs"]).all()


def test_the_recorded_tables_have_the_columns_the_body_describes(recorded_tiny_run):
    """The live graph against its description: the paper's body is joint1..joint4
    in rad with 6 receptors, so m0..m3, s0..s5 and joint1..joint4 on the wire."""
    from sensorispace_ros import contracts, messages
    from sensorispace_ros.core.body_description import BodyDescription

    bag = recorded_tiny_run
    (description,) = {messages.description_from_msg(m)
                      for _, _, _, m in read_bag_messages(bag, ["/body/description"])}
    assert description == BodyDescription.revolute(4, 6)
    for topic in ("/body/motor_command", "/body/sensation", "/agent/points_of_view",
                  "/agent/compensation_records"):
        expected = list(contracts.contract(topic).columns_for(description))
        fields = {tuple(f.name for f in m.fields)
                  for _, _, _, m in read_bag_messages(bag, [topic])}
        assert fields == {tuple(expected)}, topic
    assert expected[4:] == ["m0", "m1", "m2", "m3", "a0", "a1", "a2", "a3"]
    names = {tuple(m.name) for _, _, _, m in read_bag_messages(bag, ["/body/joint_states"])}
    assert names == {("joint1", "joint2", "joint3", "joint4")}


def test_replay_into_a_fresh_representation_node_gives_the_live_embedding(tiny_run, tmp_path):
    from sensorispace_ros.graph.nodes.representation import RESULT_FILE

    if not (tiny_run["results"] / RESULT_FILE).is_file():
        # not a replay problem: the live run has no representation to compare with
        pytest.skip("the live run's representation node failed: "
                    + tiny_run["log"].strip().splitlines()[-1])
    live = np.load(tiny_run["results"] / RESULT_FILE)
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               ROS_DOMAIN_ID=str(free_domain_id()), PYTHONPATH=str(REPO))
    representation = subprocess.Popen(
        [sys.executable, "-m", "sensorispace_ros.graph.nodes.representation", "--ros-args",
         "--params-file", str(tiny_run["config"]), "-p", f"graph.results_dir:={tmp_path}",
         "-p", "graph.exit_when_done:=true"], env=env, cwd=REPO,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        replay = subprocess.run(
            [sys.executable, "-m", "sensorispace_ros.cli", "replay", str(tiny_run["bag"]),
             "--fast", "--topics", "/body/description", "/agent/points_of_view",
             "/agent/compensations", "/agent/done"], env=env, cwd=REPO, capture_output=True, text=True, timeout=120)
        assert replay.returncode == 0, replay.stderr
        output, _ = representation.communicate(timeout=180)
    finally:
        if representation.poll() is None:
            os.kill(representation.pid, signal.SIGTERM)
            representation.wait(timeout=10)
    assert representation.returncode == 0, output
    replayed = np.load(tmp_path / RESULT_FILE)
    assert sorted(replayed.files) == sorted(live.files)
    assert "embedding_2d_iterations" in live.files, live.files
    for name in live.files:
        if name != "timings_s_json":  # wall-clock times differ, everything else must not
            np.testing.assert_array_equal(replayed[name], live[name], err_msg=name)


def test_the_bag_holds_the_run_configuration(tiny_run):
    from sensorispace_ros import config

    assert analyze.config_from_bag(tiny_run["bag"]) == config.load_config(tiny_run["config"])


def test_analyze_of_the_bag_reproduces_the_live_metrics(tiny_run, tmp_path):
    from sensorispace_ros.cli import main as cli
    from sensorispace_ros.evaluation import run_files

    live_file = tiny_run["results"] / "metrics.json"
    if not live_file.is_file():
        pytest.skip("the live run wrote no metrics.json: " + tiny_run["log"].strip().splitlines()[-1])
    assert cli.main(["analyze", str(tiny_run["bag"]), "--out", str(tmp_path)]) == 0

    def comparable(path):
        flat = run_files.flatten_metrics(run_files.read_metrics(path))
        return {k: v for k, v in flat.items()
                if not k.startswith("timings_s.") and k != "analysis.bag"}

    assert comparable(tmp_path) == comparable(live_file)


def test_analyze_builds_the_world_once_and_explores_the_paper_strategy_once(
        tiny_run, tmp_path, monkeypatch):
    counts = count_world_builds(monkeypatch)
    metrics = analyze.analyze_bag(tiny_run["bag"], tmp_path)
    assert metrics["analysis"]["naive_records"] == "evaluated by evaluation.naive"
    assert metrics["naive"]["paper_positions"] > 0 and metrics["body"]["receptors"] > 0
    assert counts == {"worlds": 1, "explorations": 1}
