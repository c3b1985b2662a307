"""The representation embeds in the dimension the agent measures, beside the
paper's 2-D and 3-D, and a run's arrays keep that embedding."""
from __future__ import annotations

import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.offline.representation import build_representation
from sensorispace_ros.evaluation.run_files import representation_from_arrays

FAST = {"representation.regularization.iterations": 1, "representation.cca.n_epochs": 5}


def _ring_of_povs(n: int = 200) -> np.ndarray:
    """POVs of one sample each on a circle of a 2-joint torus: a 1-D space."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    return np.stack([0.5 * np.cos(t), 0.5 * np.sin(t)], axis=-1)[:, None, :]


def _represent(povs, **overrides):
    cfg = config.load_config(overrides={**FAST, **overrides})
    return build_representation(povs, np.zeros((0, 2), int), np.zeros(0, int), cfg, 0,
                                processes=1)


def test_a_one_dimensional_space_gets_a_one_dimensional_embedding():
    representation = _represent(_ring_of_povs())
    assert round(representation.space_dimension()) == 1
    assert list(representation.before) == ["2d", "3d", "1d"]
    assert representation.before["1d"].shape == (200, 1)
    assert representation.iterations["1d"].shape[1:] == (200, 1)


def test_the_switch_keeps_the_paper_embeddings_only():
    representation = _represent(_ring_of_povs(), **{"representation.measured_dimension": False})
    assert list(representation.before) == ["2d", "3d"]


def test_a_plane_adds_nothing_to_the_paper_embeddings():
    g = np.linspace(-1.0, 1.0, 15)
    plane = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 1, 2)
    representation = _represent(plane)
    assert round(representation.space_dimension()) == 2
    assert list(representation.before) == ["2d", "3d"]


def test_the_arrays_of_a_run_keep_the_measured_embedding():
    representation = _represent(_ring_of_povs())
    arrays = {"hausdorff": representation.distance}
    for dim in representation.before:
        arrays[f"embedding_{dim}_before"] = representation.before[dim]
        arrays[f"embedding_{dim}_iterations"] = representation.iterations[dim]
        arrays[f"set_spread_{dim}"] = representation.set_spread[dim]
    restored = representation_from_arrays(arrays)
    assert list(restored.before) == ["2d", "3d", "1d"]
    np.testing.assert_array_equal(restored.after["1d"], representation.after["1d"])
    assert restored.space_dimension() == pytest.approx(representation.space_dimension())
