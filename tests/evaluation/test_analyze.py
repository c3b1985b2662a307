"""analyze.py: the agent's data, the ground truth, the config and the body
description come back from a bag exactly (a bag without a description: the
configured body's)."""
from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest
import yaml
from rclpy.serialization import serialize_message
from std_msgs.msg import UInt64

from sensorispace_ros.evaluation import analyze
from sensorispace_ros.recording.bag_format import (
    SESSION_CONFIG_TOPIC,
    SESSION_CONFIG_TYPE,
    BagError,
    session_config_cdr,
)
from sensorispace_ros.recording.bag_writer import BagWriter
from sensorispace_ros import contracts, messages
from sensorispace_ros.core import arm
from sensorispace_ros.core.body_description import BodyDescription

P, N = 12, 5
IDS = 10 * np.arange(P) + 3                      # ids are not positions: the mapping is tested
RECORDED = 6                                      # POVs whose first sample was commanded
CONFIG = """/**:
  ros__parameters:
    seed: 4
    world:
      grid_count: 16
    representation:
      cca:
        n_epochs: 5
      regularization:
        iterations: 2
      reaching:
        pairs: 10
        max_degree: 6
    output:
      figures: false
"""


PAPER_BODY = BodyDescription.revolute(4, 6)


def cloud(topic, table, frame_id, stamp=1, description=PAPER_BODY):
    return serialize_message(messages.table_to_cloud(
        table, contracts.contract(topic).columns_for(description),
        messages.make_header(frame_id, stamp)))


def write_run(bag, with_poses=True, config=CONFIG, pose_first=False, description=None,
              n_povs=P, done=True, withdrawn=()):
    """A recorded run; ``description``: the /body/description recorded (None:
    a bag recorded before bodies described themselves, of the paper's body);
    ``n_povs`` of the P points of view published; ``done``: /agent/done recorded;
    ``withdrawn``: the equality rows (indices) the agent withdraws at the end."""
    rng = np.random.default_rng(0)
    body = PAPER_BODY if description is None else description
    povs = rng.uniform(-np.pi, np.pi, size=(P, N, body.n_motors))
    rows = np.array([[0, 0, 1], [0, 2, 3], [1, 4, 5], [1, 6, 7], [2, 8, 9], [2, 10, 11]])
    topics = {name: c.type_name for name, c in contracts.load_contracts().items()}
    topics[SESSION_CONFIG_TOPIC] = SESSION_CONFIG_TYPE
    t = iter(range(10, 10_000))
    with BagWriter(bag, topics) as writer:
        if config is not None:
            writer.write(SESSION_CONFIG_TOPIC, 1, session_config_cdr(config))
        if description is not None:
            writer.write("/body/description", 2, serialize_message(
                messages.description_to_msg(description)))
        if with_poses:
            commanded = np.vstack([povs[:RECORDED, 0], rng.uniform(-1, 1, size=(3, 4))])
            command = cloud("/body/motor_command", {f"m{j}": commanded[:, j] for j in range(4)},
                            "cmd/1")
            # recorded poses differ from arm.forward on purpose: which one is used shows
            pose = np.asarray(arm.forward(commanded)) + 0.5
            answer = cloud("/body/sensor_pose",
                           {"x": pose[:, 0], "y": pose[:, 1], "alpha": pose[:, 2]}, "cmd/1")
            # The recorder may write the body's answer before the agent's command.
            for topic, data in ([("/body/sensor_pose", answer), ("/body/motor_command", command)]
                                if pose_first else
                                [("/body/motor_command", command), ("/body/sensor_pose", answer)]):
                writer.write(topic, next(t), data)
        for i in range(P):
            frame = f"change/{i + 1}"
            writer.write("/environment/event", next(t), cloud(
                "/environment/event", {"index": [i], "kind": [i % 2], "center_x": [0.0],
                                       "center_y": [0.0], "grid_index": [100 + i]}, frame))
            table = {"pov": np.full(N, IDS[i]), "sample": np.arange(N),
                     **{f"m{j}": povs[i, :, j] for j in range(body.n_motors)}}
            pov_cloud = cloud("/agent/points_of_view", table, frame, description=body)
            if i < n_povs:
                writer.write("/agent/points_of_view", next(t), pov_cloud)
            if i == 2 < n_povs:  # a re-send of the same message must count once
                writer.write("/agent/points_of_view", next(t), pov_cloud)
            writer.write("/agent/settled", next(t), serialize_message(UInt64(data=i + 1)))
        for k, part in enumerate((rows[:3], rows[3:]) if n_povs == P else ()):
            writer.write("/agent/compensations", next(t), cloud(
                "/agent/compensations", {"set": part[:, 0], "pov_from": IDS[part[:, 1]],
                                         "pov_to": IDS[part[:, 2]]}, f"change/{20 + k}"))
        if len(withdrawn):
            gone = rows[list(withdrawn)]
            writer.write("/agent/compensations", next(t), cloud(
                "/agent/compensations", {"set": gone[:, 0], "pov_from": IDS[gone[:, 1]],
                                         "pov_to": IDS[gone[:, 2]]}, f"withdrawn/{P + 1}"))
        totals = {column: [7] for column in contracts.contract("/agent/done").columns}
        totals.update({"changes": [P], "points_of_view": [n_povs],
                       "compensation_rows": [6 + len(withdrawn)]})
        if done:
            writer.write("/agent/done", next(t), cloud("/agent/done", totals, f"end/{P + 1}"))
    return povs, rows


def test_agent_data_is_rebuilt_like_the_representation_node_does(tmp_path):
    povs, rows = write_run(tmp_path / "bag")
    data = analyze.agent_data(tmp_path / "bag")
    assert np.array_equal(data["ids"], IDS)
    assert np.array_equal(data["povs"], povs)
    assert np.array_equal(data["pairs"], rows[:, 1:])
    assert np.array_equal(data["set_ids"], rows[:, 0])
    assert data["pov_frames"] == [f"change/{i + 1}" for i in range(P)]
    totals = analyze.agent_totals(tmp_path / "bag")
    assert set(totals) == set(contracts.contract("/agent/done").columns)
    assert (totals["changes"], totals["points_of_view"], totals["compensation_rows"]) == (P, P, 6)
    grid = {f: int(e["grid_index"]) for f, e in analyze.events(tmp_path / "bag").items()}
    assert grid == {f"change/{i + 1}": 100 + i for i in range(P)}


def test_rows_the_agent_withdraws_are_left_out_of_the_bags_sets(tmp_path):
    povs, rows = write_run(tmp_path / "bag", withdrawn=(1, 4))
    data = analyze.agent_data(tmp_path / "bag")
    left = np.delete(rows, [1, 4], axis=0)
    assert data["rows_held"] == 8 == analyze.agent_totals(tmp_path / "bag")["compensation_rows"]
    assert np.array_equal(data["pairs"], left[:, 1:])
    assert np.array_equal(data["set_ids"], left[:, 0])


@pytest.mark.parametrize("pose_first", [False, True], ids=["command_first", "pose_first"])
def test_ground_truth_comes_from_recorded_poses_then_forward_kinematics(tmp_path, pose_first):
    povs, _ = write_run(tmp_path / "bag", pose_first=pose_first)
    poses, recorded = analyze.true_poses(tmp_path / "bag", povs)
    forward = np.asarray(arm.forward(povs[:, 0]))
    assert recorded == RECORDED
    np.testing.assert_array_equal(poses[:RECORDED], forward[:RECORDED] + 0.5)
    np.testing.assert_array_equal(poses[RECORDED:], forward[RECORDED:])

    povs, _ = write_run(tmp_path / "no_poses", with_poses=False)
    poses, recorded = analyze.true_poses(tmp_path / "no_poses", povs)
    assert recorded == 0
    np.testing.assert_array_equal(poses, forward)


def test_the_body_description_comes_from_the_bag_or_from_the_configuration(tmp_path):
    small = BodyDescription(("hip", "knee"), "deg", (360.0, 360.0), 3)
    povs, _ = write_run(tmp_path / "described", with_poses=False, description=small)
    assert analyze.body_description(tmp_path / "described") == small
    data = analyze.agent_data(tmp_path / "described")
    assert data["povs"].shape == (P, N, 2) and np.array_equal(data["povs"], povs)
    write_run(tmp_path / "old")                 # no /body/description: the configured body
    assert analyze.body_description(tmp_path / "old") == PAPER_BODY


@pytest.mark.parametrize("n_povs", [0, 3])
def test_a_bag_with_too_few_povs_gives_metrics_and_a_one_line_outcome(tmp_path, n_povs):
    write_run(tmp_path / "bag", n_povs=n_povs)
    metrics = analyze.analyze_bag(tmp_path / "bag", tmp_path / "out")
    written = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert written["outcome"] == metrics["outcome"]
    assert written["outcome"].startswith(f"no representation: the agent found {n_povs} points "
                                         "of view (a representation needs at least 4)")
    assert written["agent"]["points_of_view"] == n_povs
    assert not (tmp_path / "out" / "figures").exists() or not any(
        (tmp_path / "out" / "figures").iterdir())


def test_a_bag_without_povs_or_an_end_of_run_is_nothing_to_analyse(tmp_path):
    write_run(tmp_path / "bag", n_povs=0, done=False)
    with pytest.raises(BagError, match="nothing to analyse"):
        analyze.analyze_bag(tmp_path / "bag", tmp_path / "out")


def test_config_and_seed_come_from_the_bag(tmp_path):
    write_run(tmp_path / "bag")
    cfg = analyze.config_from_bag(tmp_path / "bag")
    assert cfg["seed"] == 4 and cfg["world"]["grid_count"] == 16
    assert cfg["representation"]["regularization"]["iterations"] == 2


def test_bags_without_config_or_of_another_schema_are_one_line_errors(tmp_path):
    write_run(tmp_path / "bag", config=None)
    with pytest.raises(BagError) as error:
        analyze.analyze_bag(tmp_path / "bag", tmp_path / "out")
    assert "holds no /session/config" in str(error.value) and "\n" not in str(error.value)
    write_run(tmp_path / "bad", config="/**:\n  ros__parameters:\n    seed: -3\n")
    with pytest.raises(BagError, match="not a valid configuration: seed"):
        analyze.config_from_bag(tmp_path / "bad")
    with BagWriter(tmp_path / "other", {"/body/sensation": "std_msgs/msg/String"}):
        pass
    with pytest.raises(BagError, match="another schema"):
        analyze.analyze_bag(tmp_path / "other", tmp_path / "out")


_CORE = ("cca", "hausdorff", "regularize", "quality", "reach")
_missing = [m for m in _CORE if importlib.util.find_spec(f"sensorispace_ros.core.{m}") is None]


@pytest.mark.skipif(bool(_missing), reason=f"core modules not written yet: {_missing}")
def test_analyze_bag_equals_the_pipeline_on_the_same_data(tmp_path):
    from sensorispace_ros import config
    from sensorispace_ros.evaluation import evaluator as evaluation
    from sensorispace_ros.evaluation import run_files
    from sensorispace_ros.offline.representation import build_representation

    povs, rows = write_run(tmp_path / "bag")
    metrics = analyze.analyze_bag(tmp_path / "bag", tmp_path / "out")
    assert json.loads((tmp_path / "out" / "metrics.json").read_text())["pov"]["count"] == P

    cfg = config.load_config(overrides=yaml.safe_load(CONFIG)["/**"]["ros__parameters"])
    poses = np.asarray(arm.forward(povs[:, 0]))
    poses[:RECORDED] += 0.5
    representation = build_representation(povs, rows[:, 1:], rows[:, 0], cfg, 4)
    expected = evaluation.evaluate(representation, poses[:, :2], povs, cfg, 4)
    got = run_files.flatten_metrics(metrics)
    for key, value in expected.items():
        if key.startswith("timings_s"):
            continue
        assert got[key] == pytest.approx(value, rel=1e-9, nan_ok=True), key
    assert got["equality_sets.count"] == 3 and got["equality_sets.pairs"] == 6
    assert got["analysis.complete"] is True
    assert got["seed"] == 4


def test_stage_counters_recorded_before_the_refused_search_ends_still_decode():
    from sensorispace_ros.core.naive.records import SEARCH_FIELDS
    columns = contracts.contract("/agent/stage_counters").columns
    earlier = {name: kind for name, kind in columns.items() if name not in SEARCH_FIELDS}
    row = {name: np.array([3]) for name in earlier}
    old = messages.table_to_cloud(row, earlier, messages.make_header("end/4"))
    table = analyze.decoded_table(old, columns, later=SEARCH_FIELDS)
    assert table.dtype.names == tuple(earlier) and table["noise_quantum"][0] == 3
    with pytest.raises(messages.MessageError):
        analyze.decoded_table(old, columns)
    # A message with some of the later columns is malformed, not old.
    partial = dict(earlier, ends_between_loops=columns["ends_between_loops"])
    broken = messages.table_to_cloud({name: np.array([3]) for name in partial}, partial,
                                     messages.make_header("end/4"))
    with pytest.raises(messages.MessageError):
        analyze.decoded_table(broken, columns, later=SEARCH_FIELDS)
    new = messages.table_to_cloud({name: np.array([3]) for name in columns}, columns,
                                  messages.make_header("end/4"))
    assert analyze.decoded_table(new, columns, later=SEARCH_FIELDS)["ends_off_manifold"][0] == 3
