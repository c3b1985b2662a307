"""The evaluation's topology, diagonal and missed-position numbers on synthetic
representations, and Fig. 7a's red outlines (fast)."""
import numpy as np
import pytest

from sensorispace_ros.config import load_config
from sensorispace_ros.evaluation import evaluator as evaluation
from sensorispace_ros.evaluation import figures
from sensorispace_ros.offline.representation import Representation

SPACES = ("truth", "hausdorff", "2d.before", "2d.after", "3d.before", "3d.after")


def ring_grid(step: float = 0.25) -> np.ndarray:
    axis = np.arange(-3.0, 3.0 + 1e-9, step)
    grid = np.stack(np.meshgrid(axis, axis), axis=-1).reshape(-1, 2)
    radius = np.hypot(*grid.T)
    return grid[(radius >= 1.0) & (radius <= 3.0)]


def representation_of(before_2d: np.ndarray, after_2d: np.ndarray | None = None
                      ) -> Representation:
    after_2d = before_2d if after_2d is None else after_2d
    lift = lambda points: np.c_[points, np.zeros(len(points))]    # noqa: E731
    distance = np.linalg.norm(before_2d[:, None] - before_2d[None], axis=-1)
    return Representation(
        distance=distance, before={"2d": before_2d, "3d": lift(before_2d)},
        iterations={"2d": after_2d[None], "3d": lift(after_2d)[None]},
        set_spread={"2d": np.array([0.0, 0.0]), "3d": np.array([0.0, 0.0])})


@pytest.fixture(scope="module")
def cfg():
    # Object grid step 12 / 48 = 0.25, the step of ring_grid.
    return load_config(overrides={"representation.reaching.pairs": 10, "world.grid_count": 49})


def test_an_exact_representation_has_the_ring_topology_and_consistent_diagonals(cfg):
    positions = ring_grid()
    metrics = evaluation.evaluate(representation_of(1.7 * positions + 3.0), positions, None,
                                  cfg, seed=0)
    for space in SPACES:
        assert (metrics[f"topology.{space}.betti0"], metrics[f"topology.{space}.betti1"]) \
            == (1, 1), space
        assert metrics[f"topology.{space}.margin"] > 1.0
        lifetimes = metrics[f"topology.{space}.h1_lifetimes_top3"]
        assert lifetimes[0] > metrics[f"topology.{space}.threshold"] > lifetimes[1]
    for name in ("hausdorff", "2d.before", "2d.after", "3d.before", "3d.after"):
        assert metrics[f"metric.{name}.diagonal_ratio"] == pytest.approx(1.0)
    assert metrics["exploration.missed_in_ring"] == 0
    assert metrics["timings_s.topology"] > 0


def test_a_shear_shows_in_the_diagonal_ratio_not_in_the_unit_steps(cfg):
    positions = ring_grid()
    sheared = positions @ np.array([[1.0, 0.0], [0.3, 1.0]])
    metrics = evaluation.evaluate(representation_of(positions, sheared), positions, None, cfg,
                                  seed=0)
    assert metrics["metric.2d.before.diagonal_ratio"] == pytest.approx(1.0)
    assert metrics["metric.2d.after.diagonal_ratio"] == pytest.approx(
        np.hypot(1.3, 1.0) / np.hypot(0.7, 1.0))


def test_a_representation_cut_in_two_has_two_components_and_no_hole(cfg):
    positions = ring_grid()
    cut = positions + np.where(positions[:, :1] < 0, -20.0, 0.0) * [1.0, 0.0]
    metrics = evaluation.evaluate(representation_of(cut, positions), positions, None, cfg,
                                  seed=0)
    assert (metrics["topology.2d.before.betti0"], metrics["topology.2d.before.betti1"]) == (2, 0)
    assert (metrics["topology.2d.after.betti0"], metrics["topology.2d.after.betti1"]) == (1, 1)


def test_missed_positions_are_counted_and_outlined_in_fig07(cfg):
    positions = ring_grid()
    removed = [3, 150, 300]
    kept = np.delete(positions, removed, axis=0)
    metrics = evaluation.evaluate(representation_of(kept), kept, None, cfg, seed=0)
    assert metrics["exploration.missed_in_ring"] == 3
    missed = evaluation.missed_ring_positions(kept, 0.25)
    assert np.allclose(np.sort(missed, axis=0), np.sort(positions[removed], axis=0))

    m0 = np.asarray(cfg["arm"]["initial_motor_state"], dtype=float)
    arrays = {"grid": positions, "initial_motor_state": m0, "true_positions": kept,
              "grid_spacing": np.float64(0.25), "motor_states": np.tile(m0, (len(kept), 1)),
              "povs": np.tile(m0, (len(kept), 2, 1))}
    fig = figures.fig07_exploration(arrays)
    red = [c for c in fig.axes[0].collections
           if c.get_label().startswith("in reach, not compensated")]
    assert len(red) == 1 and red[0].get_label().endswith("(3)")
    from sensorispace_ros.core import arm
    assert np.allclose(np.sort(red[0].get_offsets() + arm.forward(m0)[:2], axis=0),
                       np.sort(positions[removed], axis=0))
    figures.plt.close(fig)
