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

import numpy as np
import pytest

from sensorispace_ros import analyze, bags

TINY = """/**:
  ros__parameters:
    seed: 0
    world:
      grid_count: 8
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


@pytest.fixture
def recorded_tiny_run(tmp_path, ros_env):
    from sensorispace_ros import launcher

    config = tmp_path / "tiny.yaml"
    config.write_text(TINY)
    log = io.StringIO()
    launcher.launch_graph(config, run="tiny", domain_id=ros_env["domain_id"],
                          record=True, results_root=tmp_path / "results",
                          bags_root=tmp_path / "bags", timeout_s=240, stream=log)
    bag = tmp_path / "bags" / "tiny"
    assert (bag / "metadata.yaml").is_file(), log.getvalue()  # closed cleanly by SIGTERM
    return bag


def test_graph_recording_drops_nothing(recorded_tiny_run):
    bag = recorded_tiny_run
    counts = bags.bag_info(bag).counts
    totals = analyze.agent_totals(bag)
    assert totals is not None, counts
    changes = totals["changes"]
    assert counts["/body/motor_command"] == totals["calls"]
    # one passive sensation per change, plus the initial one and the end
    passive = counts["/agent/settled"]
    assert passive == changes + 1
    assert counts["/body/sensation"] == totals["calls"] + passive
    assert counts["/body/sensor_pose"] == counts["/body/joint_states"] == counts["/body/sensation"]
    assert counts["/environment/lights"] == passive
    # /agent/done counts the end as a change: the events are change/1 .. change/<changes - 1>
    assert counts["/environment/event"] == changes - 1
    data = analyze.agent_data(bag)
    assert len(data["ids"]) == totals["points_of_view"]
    assert len(data["pairs"]) == totals["compensation_rows"]
    # every recorded sensor pose answers a recorded command row
    _, recorded = analyze.true_poses(bag, data["povs"])
    assert recorded == len(data["ids"])
    settled = [m.data for _, _, _, m in bags.read_bag_messages(bag, ["/agent/settled"])]
    assert settled == list(range(len(settled)))
    assert np.isfinite(data["povs"]).all()
