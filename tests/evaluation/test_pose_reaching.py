"""Reaching in pose space as the evaluation runs it: the poses and the length
scale reach ``core.pose_reach`` right, and only a turning world gets the keys."""
from __future__ import annotations

import sys
from types import SimpleNamespace

import numpy as np
import pytest
from shared import REPO, SMOKE

from sensorispace_ros import config
from sensorispace_ros.core.arm import PAPER_ARM, Arm
from sensorispace_ros.core.pose_reach import pose_distance
from sensorispace_ros.evaluation import reproduce
from sensorispace_ros.evaluation.pose_reaching import pose_length_scale, pose_reaching_numbers

sys.path.insert(0, str(REPO))
from bench import pose_reaching as pose_reaching_bench  # noqa: E402


def test_an_angle_weighs_as_the_arc_at_the_middle_of_the_working_ring():
    assert pose_length_scale(PAPER_ARM) == pytest.approx(2.0)         # 1 <= |tip| <= 3
    assert pose_length_scale(Arm((2.0, 1.0), "joint", "rad")) == pytest.approx(2.5)


def _ring_times_circle(n_theta=16):
    """Poses of the paper arm's working ring x circle, an angle step of 2 pi / n_theta."""
    radii, bearings = np.meshgrid(np.linspace(1.2, 2.8, 5), np.linspace(0, 2 * np.pi, 24,
                                                                        endpoint=False))
    xy = np.column_stack([(radii * np.cos(bearings)).ravel(), (radii * np.sin(bearings)).ravel()])
    theta = np.arange(n_theta) * 2 * np.pi / n_theta
    return np.array([(x, y, t) for x, y in xy for t in theta])


def test_the_evaluation_scores_the_graphs_on_the_run_poses():
    poses = _ring_times_circle()
    true = pose_distance(poses[:, None], poses[None], 2.0)
    cut = np.column_stack([poses[:, :2], 2.0 * np.mod(poses[:, 2], 2 * np.pi)])
    representation = SimpleNamespace(distance=true, before={"3d": None},
                                     embedding=lambda dim, stage: cut)
    cfg = {"representation": {"reaching": {"pairs": 200, "max_degree": 50, "radius": 1.0}},
           "arm": {"segments": [1.0, 1.0, 1.0], "eye": "joint", "motor_unit": "rad"}}
    flipped = 3.0 - poses[:, 2]                        # an angle coordinate, turning the other way
    numbers = pose_reaching_numbers(representation, poses, cfg, seed=0, angle=flipped)
    assert numbers["pose_reaching.length_scale"] == pytest.approx(2.0)
    assert numbers["pose_reaching.hausdorff.reached_share"] == 1.0
    assert numbers["pose_reaching.hausdorff.long_way_share"] == 0.0
    assert numbers["pose_reaching.3d.before.long_way_share"] > 0.1       # the cut embedding
    assert (numbers["pose_reaching.3d.after.straightness_median"]
            > numbers["pose_reaching.hausdorff.straightness_median"])
    assert numbers["pose_reaching.hausdorff.straightness_p90"] < 1.5
    assert numbers["pose_reaching.angle.short_way_share"] == 1.0
    assert numbers["pose_reaching.angle.scored"] > 150               # the 200 pairs, less ties
    assert "pose_reaching.angle.short_way_share" not in pose_reaching_numbers(
        representation, poses, cfg, seed=0)


TURNING = {"world.grid_count": 12, "world.rotation_count": 4, "output.figures": False,
           "representation.regularization.iterations": 2, "representation.cca.n_epochs": 10}


def test_a_turning_run_reports_pose_reaching_and_a_translation_run_does_not(tmp_path):
    turning = reproduce.reproduce(config.load_config(SMOKE, TURNING), "paper",
                                  out_dir=tmp_path / "turning", figures=False)
    hausdorff = turning["pose_reaching"]["hausdorff"]
    unreached = turning["reaching"]["hausdorff"]["unreachable"]       # same pairs, same graph
    assert hausdorff["reached_share"] == pytest.approx(1.0 - unreached / 30) and unreached < 15
    assert 1.0 <= hausdorff["straightness_median"] < 2.0
    assert {"2d", "3d"} <= set(turning["pose_reaching"])
    again = pose_reaching_bench.measure(str(tmp_path / "turning"), 30)    # from the arrays
    assert again["pose_reaching.hausdorff.straightness_median"] == hausdorff["straightness_median"]
    assert again["pose_reaching.3d.after.long_way_share"] == \
        turning["pose_reaching"]["3d"]["after"]["long_way_share"]
    flat = reproduce.reproduce(config.load_config(SMOKE, {"output.figures": False}), "paper",
                               out_dir=tmp_path / "flat", figures=False)
    assert "pose_reaching" not in flat and "reaching" in flat
