"""The README's result table is the one scripts/readme_results.py renders from
docs/readme-metrics/<strategy>-seed0/metrics.json, and those files were made with
the current config/paper.yaml (a run of both strategies takes minutes of a
core, too long for the suite: the script makes them again in one command)."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from sensorispace_ros import config

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "scripts" / "readme_results.py"


@pytest.fixture(scope="module")
def script():
    spec = importlib.util.spec_from_file_location("readme_results", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_readme_table_is_rendered_from_the_committed_metrics(script):
    before, after = script.rendered_readme()
    assert before == after, "README.md's result table differs: run scripts/readme_results.py"


@pytest.mark.parametrize("strategy", ["paper", "naive"])
def test_the_committed_metrics_come_from_the_current_paper_config(script, strategy):
    metrics = json.loads(script.metrics_path(strategy).read_text())
    assert metrics["strategy"] == strategy and metrics["seed"] == 0
    # The script's runs draw no figures (``--no-figures``), which the config echoes.
    current = config.flatten(config.load_config(REPO / "config" / "paper.yaml",
                                                {"output.figures": False}))
    assert metrics["config"] == json.loads(json.dumps(current))


def test_a_changed_number_changes_the_table(script, tmp_path):
    """The check fails when a number drifts: one metric changed, the README differs."""
    for strategy in script.STRATEGIES:
        target = script.metrics_path(strategy, tmp_path)
        target.parent.mkdir(parents=True)
        metrics = json.loads(script.metrics_path(strategy).read_text())
        if strategy == "naive":
            metrics["naive"]["calls_total"] += 1
        target.write_text(json.dumps(metrics))
    before, after = script.rendered_readme(tmp_path)
    assert before != after
    calls = json.loads(script.metrics_path("naive").read_text())["naive"]["calls_total"]
    assert f"/ {calls + 1:,} /" in after and f"/ {calls:,} /" in before


def test_numbers_are_written_as_the_table_writes_them(script):
    assert script.sci(1.14e-6) == "1.1e-6" and script.sci(4.4e-14) == "4.4e-14"
    assert script.sci(0.00026) == "2.6e-4"
