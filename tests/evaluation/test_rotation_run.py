"""A run of a turning world end to end (``reproduce``): the paper strategy
compensates the compensable (position, orientation) poses and the run's
metrics carry the Betti numbers up to H2 and the angle coordinate."""
from __future__ import annotations

import numpy as np
from shared import SMOKE

from sensorispace_ros import config
from sensorispace_ros.core.run_world import run_world
from sensorispace_ros.evaluation import reproduce
from sensorispace_ros.evaluation.rotations import compensable_poses, draw_orientation_figure

TURNING = {"world.grid_count": 12, "world.rotation_count": 4, "output.figures": False,
           "representation.regularization.iterations": 2, "representation.cca.n_epochs": 10}


def test_a_paper_run_of_a_turning_world(tmp_path):
    cfg = config.load_config(SMOKE, TURNING)
    metrics = reproduce.reproduce(cfg, "paper", out_dir=tmp_path, figures=False)
    pairs, _ = compensable_poses(run_world(cfg))
    assert metrics["exploration"]["compensated"] == len(pairs)
    assert metrics["exploration"]["state_changes_compensated"] == 0
    for space in ("truth", "hausdorff", "2d.before", "3d.after"):
        node = metrics["topology_h2"]
        for part in space.split("."):
            node = node[part]
        assert node["betti0"] >= 1 and {"betti1", "betti2"} <= set(node)
    assert 0.0 <= metrics["rotation"]["angle_circular_correlation"] <= 1.0
    assert metrics["equality_sets"]["count"] > 0          # translations within an orientation
    arrays = np.load(tmp_path / "arrays.npz")
    figure = draw_orientation_figure(dict(arrays), None, tmp_path / "figure.png")
    assert figure.stat().st_size > 10_000
