"""Offline pipeline: smoke reproduce end to end, determinism, evaluation numbers."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from sensorispace_ros.evaluation import evaluator as evaluation
from sensorispace_ros.evaluation import figures, reproduce, run_files, runs, space_figures
from sensorispace_ros.offline import strategies
from sensorispace_ros.offline.representation import DIMENSIONS, Representation, build_representation
from sensorispace_ros.config import load_config

from shared import SMOKE

REQUIRED_KEYS = [
    "exploration.events", "exploration.state_changes", "exploration.compensated",
    "exploration.state_changes_compensated", "pov.count", "pov.max_pose_drift",
    *[f"quality.{d}.{s}.{q}" for d in ("2d", "3d") for s in ("before", "after")
      for q in ("trustworthiness", "continuity", "spearman", "affine_residual")],
    *[f"reaching.{d}.{s}.straightness_median" for d in ("2d", "3d") for s in ("before", "after")],
    "reaching.hausdorff.straightness_median",
    *[f"timings_s.{t}" for t in ("exploration", "points_of_view", "hausdorff", "cca",
                                 "regularization", "reaching", "total")],
    # numbers for what the paper only shows as pictures
    "regularization.2d.set_spread", "regularization.3d.set_spread",
    "quality.2d.before.neighbours_true_fraction", "metric.2d.before.unit_step_cv",
    "metric.hausdorff.unit_step_cv", "equality_sets.count", "equality_sets.pairs",
]


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("smoke")
    metrics = reproduce.reproduce(load_config(SMOKE), "paper", out_dir=out)
    return out, metrics


def flat(metrics: dict) -> dict:
    return run_files.flatten_metrics({k: v for k, v in metrics.items() if k != "config"})


def test_smoke_run_has_every_metric(smoke_run):
    _, metrics = smoke_run
    values = flat(metrics)
    missing = [key for key in REQUIRED_KEYS if key not in values]
    assert not missing
    for key in REQUIRED_KEYS:
        value = values[key]
        numbers = value if isinstance(value, list) else [value]
        assert numbers and all(isinstance(v, (int, float)) and math.isfinite(v)
                               for v in numbers), (key, value)
    assert metrics["strategy"] == "paper" and metrics["seed"] == 0
    assert metrics["config"]["world.grid_count"] == 16       # the flattened config used


def test_smoke_run_counts_are_consistent(smoke_run):
    out, metrics = smoke_run
    arrays = np.load(out / run_files.ARRAYS_FILE)
    n_pov = metrics["pov"]["count"]
    # m0 is a POV of its own, then one per compensation (all valid in the ring).
    assert n_pov == metrics["exploration"]["compensated"] + 1 - metrics["pov"]["invalid"]
    assert arrays["povs"].shape == (n_pov, 50, 4)
    # The paper's shortcut relates every pair of grid positions by one
    # displacement; the object starts on the grid, so the initial POV is one
    # of them.
    assert metrics["equality_sets"]["pairs"] == n_pov * (n_pov - 1) // 2
    iterations = load_config(SMOKE)["representation"]["regularization"]["iterations"]
    # spread of the Hausdorff metric, then after each iteration
    assert len(metrics["regularization"]["2d"]["set_spread"]) == iterations + 1
    assert arrays["embedding_3d_iterations"].shape == (iterations, n_pov, 3)
    assert metrics["exploration"]["state_changes_compensated"] == 0
    assert metrics["timings_s"]["total"] >= sum(
        metrics["timings_s"][k] for k in ("exploration", "points_of_view", "hausdorff", "cca",
                                          "regularization", "reaching"))


def test_regularisation_makes_the_metric_regular(smoke_run):
    """The paper's claim, as numbers: equal external grid steps get more equal
    internal lengths, and reaching gets straighter, in 2-D."""
    _, metrics = smoke_run
    metric = metrics["metric"]["2d"]
    assert metric["after"]["unit_step_cv"] < metric["before"]["unit_step_cv"]
    quality = metrics["quality"]["2d"]
    assert quality["after"]["affine_residual"] < quality["before"]["affine_residual"]


def test_smoke_run_writes_every_figure(smoke_run):
    out, _ = smoke_run
    import matplotlib.image

    for name in figures.FIGURES:
        path = out / run_files.FIGURES_DIR / f"{name}.png"
        assert path.is_file(), name
        image = matplotlib.image.imread(path)
        assert image.shape[0] > 300 and image.shape[1] > 300
        assert image[..., :3].std() > 0.05, f"{name} looks blank"
    # Fig. 6 (drawn in a forked process) is the figure of the stored example POVs
    arrays = np.load(out / run_files.ARRAYS_FILE)
    assert arrays["pov_example"].shape[1] == 4 and arrays["pov_examples_x"].ndim == 3


def test_reaching_examples_skip_pairs_a_pruned_graph_does_not_connect():
    """A representation in two far clusters (pruned graph disconnected, as a
    short graph run can give): the figure draws pairs within a cluster."""
    rng = np.random.default_rng(0)
    positions = rng.uniform(0, 6, size=(40, 2))
    embedding = np.vstack([positions[:20], positions[20:] + 100.0])
    cfg = load_config(SMOKE, overrides={"representation.reaching.max_degree": 5})
    arrays = {"config_json": json.dumps(cfg), "true_positions": positions,
              "povs": rng.uniform(0, 1, size=(40, 3, 4)),
              "embedding_2d_before": embedding, "embedding_2d_iterations": embedding[None]}
    examples = space_figures.reaching_examples(arrays, "2d", count=3)
    assert len(examples["starts"]) == 3
    for start, target in zip(examples["starts"], examples["targets"]):
        assert (start < 20) == (target < 20)


def test_draw_all_draws_only_the_named_figures(smoke_run, tmp_path):
    out, _ = smoke_run
    arrays = dict(np.load(out / run_files.ARRAYS_FILE))
    written = figures.draw_all(arrays, tmp_path, only=["fig08_projections_before"])
    assert [p.name for p in written] == ["fig08_projections_before.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig08_projections_before.png"]
    with pytest.raises(ValueError, match="unknown"):
        figures.draw_all(arrays, tmp_path, only=["fig99"])


def test_metrics_json_is_sorted_and_rounded(smoke_run):
    out, _ = smoke_run
    text = (out / run_files.METRICS_FILE).read_text()

    def check_sorted(pairs):
        keys = [k for k, _ in pairs]
        assert keys == sorted(keys)
        return dict(pairs)
    json.loads(text, object_pairs_hook=check_sorted)
    assert "NaN" not in text and "Infinity" not in text


def test_same_seed_gives_the_same_metrics(smoke_run, tmp_path):
    _, first = smoke_run
    cfg = load_config(SMOKE, overrides={"output.figures": False})
    second = reproduce.reproduce(cfg, "paper", out_dir=tmp_path)
    first, second = json.loads(json.dumps(first)), json.loads(json.dumps(second))
    for run in (first, second):
        run.pop("timings_s")
        run["config"].pop("output.figures")
    assert first == second


def test_chains_in_two_processes_equal_one_process(smoke_run):
    """The 2-D and 3-D chains have their own seeded streams: running them in
    two processes changes no bit."""
    out, _ = smoke_run
    arrays = dict(np.load(out / run_files.ARRAYS_FILE))
    cfg = json.loads(str(arrays["config_json"]))
    cfg["representation"]["regularization"]["iterations"] = 2
    runs = [build_representation(arrays["povs"], arrays["pairs"], arrays["set_ids"],
                                 cfg, int(arrays["seed"]), processes=processes)
            for processes in (1, 2)]
    for dim in DIMENSIONS:
        assert np.array_equal(runs[0].before[dim], runs[1].before[dim])
        assert np.array_equal(runs[0].iterations[dim], runs[1].iterations[dim])
        assert np.array_equal(runs[0].set_spread[dim], runs[1].set_spread[dim])
        assert runs[0].iterations[dim].shape[0] == 2
    # the smoke run itself (default processes) gave the same first iteration
    assert np.array_equal(runs[0].before["2d"], arrays["embedding_2d_before"])
    with pytest.raises(ValueError, match="processes"):
        build_representation(arrays["povs"], arrays["pairs"], arrays["set_ids"], cfg,
                             0, processes=0)


def test_points_of_view_in_two_processes_equal_one_batch():
    """The kernel walk is per POV: halves of the batch in two processes give
    the same bits as one batch."""
    cfg = load_config(SMOKE)
    rng = np.random.default_rng(3)
    motor = np.array(cfg["arm"]["initial_motor_state"]) + rng.uniform(-1.0, 1.0, (64, 4))
    one = strategies._sample_points_of_view(motor, cfg, processes=1)
    two = strategies._sample_points_of_view(motor, cfg, processes=2)
    assert np.array_equal(one.samples, two.samples)
    assert np.array_equal(one.valid, two.valid) and one.reason == two.reason
    assert np.array_equal(one.steps, two.steps) and np.array_equal(one.winding, two.winding)
    assert one.max_pose_drift == two.max_pose_drift
    assert one.samples.shape == (64, cfg["pov"]["n_samples"], 4) and one.valid.sum() > 32


def test_run_arrays_reproduce_the_evaluation(smoke_run):
    """arrays.npz alone gives back the representation's numbers."""
    out, metrics = smoke_run
    arrays = dict(np.load(out / run_files.ARRAYS_FILE))
    cfg = json.loads(str(arrays["config_json"]))
    representation = run_files.representation_from_arrays(arrays)
    again = evaluation.evaluate(representation, arrays["true_positions"], arrays["povs"], cfg,
                              int(arrays["seed"]))
    again.pop("timings_s.reaching")
    again.pop("timings_s.topology")
    written = flat(metrics)
    for key, value in again.items():
        expected = written[key]
        if isinstance(value, list):
            np.testing.assert_allclose(value, expected, rtol=1e-10)
        elif isinstance(value, float) and math.isnan(value):
            assert expected is None
        else:
            assert value == pytest.approx(expected, rel=1e-10, abs=1e-12), key


def test_graph_run_evaluation_matches_reproduce(smoke_run, tmp_path):
    """The ROS side hands over only the agent's arrays; ground truth comes from
    the forward model and the numbers are those of ``reproduce``."""
    out, metrics = smoke_run
    stored = np.load(out / run_files.ARRAYS_FILE)
    agent_side = {key: stored[key] for key in
                  ("povs", "pairs", "set_ids", "hausdorff", "embedding_2d_before",
                   "embedding_3d_before", "embedding_2d_iterations", "embedding_3d_iterations",
                   "set_spread_2d", "set_spread_3d")}
    cfg = load_config(SMOKE, overrides={"output.figures": False})
    graph = runs.evaluate_graph_run(agent_side, cfg, tmp_path,
                                          metrics={"naive.coverage": 1.0})
    assert (tmp_path / run_files.METRICS_FILE).is_file()
    assert graph["naive"]["coverage"] == 1.0
    for dim in ("2d", "3d"):
        for stage in ("before", "after"):
            for key in ("trustworthiness", "affine_residual"):
                assert graph["quality"][dim][stage][key] == pytest.approx(
                    metrics["quality"][dim][stage][key], rel=1e-6, abs=1e-9)
    assert graph["reaching"]["2d"]["after"]["straightness_median"] == pytest.approx(
        metrics["reaching"]["2d"]["after"]["straightness_median"], rel=1e-9)
    assert graph["pov"]["max_pose_drift"] <= 1e-6


# ---------------------------------------------------------------------------
# Evaluation numbers on synthetic representations (fast)


def ring_grid(step: float = 0.5) -> np.ndarray:
    axis = np.arange(-3.0, 3.0 + 1e-9, step)
    grid = np.stack(np.meshgrid(axis, axis), axis=-1).reshape(-1, 2)
    radius = np.hypot(*grid.T)
    return grid[(radius >= 1.0) & (radius <= 3.0)]


def representation_of(points_2d: np.ndarray) -> Representation:
    points_3d = np.c_[points_2d, np.zeros(len(points_2d))]
    distance = np.linalg.norm(points_2d[:, None] - points_2d[None], axis=-1)
    return Representation(
        distance=distance, before={"2d": points_2d, "3d": points_3d},
        iterations={"2d": points_2d[None], "3d": points_3d[None]},
        set_spread={"2d": np.array([0.0, 0.0]), "3d": np.array([0.0, 0.0])})


def test_evaluation_of_an_exact_representation():
    positions = ring_grid()
    cfg = load_config(overrides={"representation.reaching.pairs": 20})
    # An affine image of the truth (rotation, scale, shift) is perfect.
    angle = 0.7
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    metrics = evaluation.evaluate(representation_of(2.5 * positions @ rotation.T + 4.0),
                                positions, None, cfg, seed=0)
    assert metrics["quality.2d.before.affine_residual"] < 1e-9
    assert metrics["quality.3d.after.affine_residual"] < 1e-9
    assert metrics["metric.2d.before.unit_step_cv"] < 1e-9
    assert metrics["quality.2d.before.neighbours_true_fraction"] == 1.0
    assert metrics["regularization.2d.set_spread"] == [0.0, 0.0]
    # (ties of the grid's distances are broken by rounding after the rotation)
    assert metrics["metric.hausdorff.spearman"] == pytest.approx(1.0, abs=1e-3)


def test_evaluation_of_a_warped_representation_is_worse():
    positions = ring_grid()
    cfg = load_config(overrides={"representation.reaching.pairs": 20})
    # Radial warp (|x| -> |x|^2) keeps topology but breaks the metric.
    radius = np.hypot(*positions.T)[:, None]
    warped = positions * radius
    metrics = evaluation.evaluate(representation_of(warped), positions, None, cfg, seed=0)
    assert metrics["quality.2d.before.affine_residual"] > 0.05
    assert metrics["metric.2d.before.unit_step_cv"] > 0.2


def test_neighbours_true_fraction_counts_swapped_points():
    positions = ring_grid()
    embedding = positions.copy()
    # Swap two far-apart POVs: each now sits among strangers.
    far = int(np.argmax(np.linalg.norm(positions - positions[0], axis=1)))
    embedding[[0, far]] = embedding[[far, 0]]
    fraction = evaluation._neighbours_true_fraction(embedding, positions)
    # the two swapped POVs, and POVs that now find a stranger among their nearest
    assert fraction <= 1.0 - 3 / len(positions)
    assert evaluation._neighbours_true_fraction(positions, positions) == 1.0


def test_neighbours_true_fraction_allows_ties_off_the_exact_lattice():
    """Compensated positions sit up to the compensation threshold off the
    lattice: a diagonal tie stays a tie."""
    positions = ring_grid()
    spacing = np.min(np.linalg.norm(positions[1:] - positions[0], axis=1))
    jittered = positions + np.random.default_rng(0).uniform(-5e-3, 5e-3, positions.shape) * spacing
    assert evaluation._neighbours_true_fraction(positions, jittered) == 1.0


def test_unit_step_cv_by_hand():
    distance = np.array([[0.0, 1.0, 3.0], [1.0, 0.0, 2.0], [3.0, 2.0, 0.0]])
    # lengths 1 and 3: std 1, mean 2
    assert evaluation._unit_step_cv(distance, np.array([[0, 1], [0, 2]])) == pytest.approx(0.5)
    assert evaluation._unit_step_cv(distance, np.array([[0, 1], [1, 0]])) == 0.0


# ---------------------------------------------------------------------------
# metrics.json helpers


def test_write_metrics_rounds_sorts_and_nulls_non_finite(tmp_path):
    path = tmp_path / "m.json"
    run_files.write_metrics({"b": {"y": 0.1 + 0.2, "x": float("nan")}, "a": np.int64(3),
                            "c": [np.float64(1.0) / 3.0, float("inf")]}, path)
    text = path.read_text()
    assert text.index('"a"') < text.index('"b"') and text.index('"x"') < text.index('"y"')
    loaded = json.loads(text)
    assert loaded == {"a": 3, "b": {"x": None, "y": 0.3}, "c": [0.333333333333, None]}


def test_nest_and_flatten_are_inverse_and_collisions_raise():
    flat_metrics = {"a.b": 1, "a.c.d": 2.5, "e": "x"}
    assert run_files.flatten_metrics(run_files.nest(flat_metrics)) == flat_metrics
    with pytest.raises(ValueError):
        run_files.nest({"a": 1, "a.b": 2})


def test_unknown_strategy_is_rejected(tmp_path):
    with pytest.raises(ValueError, match="strategy must be one of paper, naive"):
        reproduce.reproduce(load_config(SMOKE), "clever", out_dir=tmp_path)
