"""The two scripts of examples/ run as a researcher runs them (a fresh
process, from the repository root) and print the agent's coverage."""
from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest
from shared import REPO

COVERAGE = re.compile(r"coverage (\d\.\d\d) \((\d+) of (\d+) positions")


def run_example(name: str, *args: str, timeout: float) -> str:
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "PYTHONPATH": os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH"))
                                         if p)}
    done = subprocess.run([sys.executable, str(REPO / "examples" / name), *args], cwd=REPO,
                          env=env, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


def test_the_naive_agent_on_a_plain_sense_function_covers_the_positions_it_was_shown():
    out = run_example("naive_agent_on_your_body.py", timeout=300)
    coverage, covered, shown = COVERAGE.search(out).groups()
    assert int(shown) == 17                      # a 4 x 4 grid and the start
    assert float(coverage) == pytest.approx(int(covered) / int(shown), abs=0.005)
    assert int(covered) >= 12, out
    assert "representation: ['2d', '3d'] embeddings" in out


@pytest.mark.graph
@pytest.mark.timeout(900)
def test_the_in_process_graph_example_prints_the_offline_runs_coverage(tmp_path,
                                                                       smoke_naive_reference):
    out = run_example("graph_in_process.py", str(REPO / "config" / "smoke.yaml"),
                      str(tmp_path / "results"), timeout=900)
    coverage, covered, _ = COVERAGE.search(out).groups()
    expected = smoke_naive_reference.metrics
    assert float(coverage) == pytest.approx(expected["naive.coverage"], abs=0.005)
    assert int(covered) == expected["naive.distinct_positions"]
    assert (tmp_path / "results" / "metrics.json").is_file()
