"""bench/noise_study.py's rows and table: what each run's metrics.json says,
one row a setting, and nothing per POV where no POV was found."""
import json
import subprocess
import sys

import pytest

from shared import REPO
sys.path.insert(0, str(REPO / "bench"))

import noise_study  # noqa: E402


def write_run(folder, metrics: dict) -> str:
    folder.mkdir()
    (folder / "metrics.json").write_text(json.dumps(metrics))
    return str(folder)


FOUND = {"pov": {"count": 505},
         "naive": {"pose_rank": 3, "pov_dim": 1, "space_dim": 2, "coverage": 0.775,
                   "coverage_of_paper_positions": 0.774, "wrong_poses": 5,
                   "state_changes_accepted": 0, "pose_error_median": 1.3e-3,
                   "pose_error_p95": 6.3e-3, "queries_per_pov": 637.25,
                   "queries_total_per_pov": 9922.7, "queries_total": 5010951},
         "quality": {"2d": {"after": {"affine_residual": 0.1505, "trustworthiness": 0.9977}}},
         "topology": {"2d": {"after": {"betti0": 1, "betti1": 1}}}}


def test_a_row_reads_the_structure_the_betti_numbers_and_the_metrics(tmp_path):
    row = noise_study.row_of(write_run(tmp_path / "run", FOUND), "noise 1e-4", 246.8)
    assert row["structure"] == "3, 1, 2" and row["betti"] == "1/1"
    assert row["naive.coverage_of_paper_positions"] == 0.774
    assert row["naive.queries_total_per_pov"] == 9922.7 and row["wall_s"] == 246.8
    line = noise_study.table([row]).splitlines()[2]
    assert line.startswith("| noise 1e-4 | 3, 1, 2 | 505 | 0.775 | 0.774 | 5 | 0 |")
    assert "| 9,923 | 5,010,951 | 246.8 |" in line      # large counts with separators


def test_a_run_without_povs_has_nothing_per_pov_and_no_pose_error(tmp_path):
    nothing = {"pov": {"count": 0},
               "naive": {"pose_rank": 2, "pov_dim": 2, "coverage": 0.0, "wrong_poses": 0,
                         "pose_error_median": 0.0, "pose_error_p95": 0.0,
                         "queries_per_pov": 0.0, "queries_total_per_pov": 2315789.0,
                         "queries_total": 2315789}}
    row = noise_study.row_of(write_run(tmp_path / "run", nothing), "noise 1e-2", 57.1)
    assert row["structure"] == "2, 2, —" and row["betti"] == "—/—"
    for key in ("naive.queries_per_pov", "naive.queries_total_per_pov",
                "naive.pose_error_median", "naive.pose_error_p95"):
        assert row[key] is None, key
    assert "| — | — | 2,315,789 |" in noise_study.table([row])


@pytest.mark.parametrize("value, text", [(None, "—"), (0.99961, "0.9996"), (8870.2, "8,870"),
                                         (5748048, "5,748,048"), (3, "3"), (1.116e-6, "1.116e-06")])
def test_cells(value, text):
    assert noise_study.cell(value) == text


def test_no_job_to_run_on_is_refused_before_any_run(tmp_path):
    done = subprocess.run([sys.executable, str(REPO / "bench" / "noise_study.py"), "--jobs", "0",
                           "--out", str(tmp_path / "out")], capture_output=True, text=True)
    assert done.returncode == 2 and "--jobs: must be >= 1, got 0" in done.stderr
    assert not (tmp_path / "out").exists()
