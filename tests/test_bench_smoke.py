"""The benchmark runner runs on a tiny input and its checks mean something
(no timing assertions: timings belong to bench/, not to tests)."""
import json
import sys

import numpy as np
import pytest

from sensorispace_ros.core.numpy_math import numpy_calls_c_math

from shared import REPO
sys.path.insert(0, str(REPO))

from bench import run_all, scale  # noqa: E402


@pytest.mark.numpy_bits      # re-run where NumPy calls the C library's exp (core.numpy_math)
def test_run_all_on_tiny_povs_writes_json_and_baselines_agree(tmp_path, capsys):
    rng = np.random.default_rng(3)
    P, N = 12, 8
    # Loops around random centres, like POVs: angles far outside [0, 2 pi) on purpose.
    centres = rng.uniform(-9, 9, size=(P, 1, 4))
    phase = np.linspace(0, 2 * np.pi, N, endpoint=False)[None, :, None]
    povs = centres + 0.3 * np.sin(phase + rng.uniform(0, 6, size=(P, 1, 4)))
    pairs = np.array([[0, 1], [2, 3], [4, 5], [1, 6], [7, 8]])
    set_ids = np.array([0, 0, 1, 1, 2])
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    np.savez(run_dir / "arrays.npz", povs=povs, pairs=pairs, set_ids=set_ids)
    out = tmp_path / "bench.json"

    assert run_all.main(["--quick", "--skip", "end_to_end,probe", "--povs-from", str(run_dir),
                         "--out", str(out)]) == 0

    results = json.loads(out.read_text())
    assert results["povs_source"] == str(run_dir)
    hausdorff = results["hausdorff"]
    assert hausdorff["povs"] == [P, N, 4]
    assert hausdorff["max_abs_diff"] <= 1e-12 and hausdorff["max_abs_diff_1thread"] <= 1e-12
    assert hausdorff["numpy_path_max_abs_diff"] <= 1e-12
    for dim in ("2d", "3d"):
        # The reference CCA is an independent transcription of the update rule.
        assert results["cca"]["cca"]["dims"][dim]["max_abs_diff_vs_baseline"] < 1e-9
        # compiled or not, the fitted CCA is the NumPy loop's, to the bit (within a few
        # ulp where NumPy's exp is its own, not the compiled loop's C library exp)
        assert results["cca"]["cca"]["dims"][dim]["max_abs_diff_vs_numpy_loop"] \
            <= (0.0 if numpy_calls_c_math() else 1e-12)
    assert results["cca"]["regularization"]["averaging_max_abs_diff"] < 1e-12
    assert "hausdorff matrix" in capsys.readouterr().out


def test_fit_exponent_recovers_a_power_law():
    counts = np.array([160, 650, 2600])
    assert abs(scale.fit_exponent(counts, 3e-6 * counts ** 2.0) - 2.0) < 1e-9
    assert abs(scale.fit_exponent(counts, 0.01 * counts ** 1.0) - 1.0) < 1e-9
    assert scale.fit_exponent([650], [1.0]) is None


def test_graph_walltime_offline_side_does_the_graphs_work_without_evaluation():
    """The graph bench times, as its offline side, a fresh process that explores and
    builds the representation (what the graph does), not the ground-truth evaluation."""
    import os
    import subprocess

    from sensorispace_ros import config
    from sensorispace_ros.evaluation.ground_truth import RunTruth
    from sensorispace_ros.evaluation.naive import join_naive_run
    from sensorispace_ros.offline import strategies
    smoke = str(REPO / "config" / "smoke.yaml")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        p for p in (str(REPO), os.environ.get("PYTHONPATH")) if p)}
    done = subprocess.run([sys.executable, str(REPO / "bench" / "graph_walltime.py"),
                           "--offline-child", "--config", smoke], env=env,
                          capture_output=True, text=True, cwd=REPO, timeout=300, check=True)
    stages = json.loads(done.stdout.strip().splitlines()[-1])
    cfg = config.load_config(smoke)
    produced = strategies.run_naive_strategy(cfg, cfg["seed"])
    join_naive_run(produced, RunTruth(cfg, produced.world))
    assert stages["points_of_view"] == produced.metrics["pov.count"] > 10
    assert stages["calls"] == produced.metrics["naive.calls_total"]
    assert set(stages) >= {"import_s", "exploration_s", "representation_s"}
    # The evaluator's join also runs the paper strategy for the coverage denominator:
    # the part of the offline pipeline the bench leaves out, as the graph does.
    assert produced.timings_s["naive_ground_truth"] > 0
