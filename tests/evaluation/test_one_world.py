"""One evaluation builds the run's world once (``core.run_world``) and runs the
paper exploration behind the naive coverage denominator once, whichever path
the run takes: ``reproduce`` of either strategy, or a graph run evaluated from
what its nodes wrote."""
from __future__ import annotations

import numpy as np
import pytest
from shared import SMOKE, count_world_builds

from sensorispace_ros import config
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.records import NaiveAgentRecords
from sensorispace_ros.core.naive.run import run_naive
from sensorispace_ros.core.run_world import run_world
from sensorispace_ros.evaluation import graph_run, reproduce, run_files
from sensorispace_ros.offline.representation import build_representation
from sensorispace_ros.offline.strategies import StrategyOutput
from sensorispace_ros.protocol import AGENT_RECORDS_FILE, RESULT_FILE

SMALL = {"world.grid_count": 12, "output.figures": False,
         "representation.regularization.iterations": 2, "representation.cca.n_epochs": 10}


@pytest.fixture(scope="module")
def cfg():
    return config.load_config(SMOKE, SMALL)


@pytest.mark.parametrize("strategy", ["paper", "naive"])
def test_reproduce_builds_one_world_and_explores_once(cfg, strategy, tmp_path, monkeypatch):
    counts = count_world_builds(monkeypatch)
    metrics = reproduce.reproduce(cfg, strategy, out_dir=tmp_path)
    assert metrics["body"]["receptors"] == cfg["world"]["retina"]["receptors"]
    if strategy == "naive":
        assert metrics["naive"]["paper_positions"] > 0
    assert counts == {"worlds": 1, "explorations": 1}


def test_a_graph_run_without_its_bag_builds_one_world_and_explores_once(cfg, tmp_path,
                                                                        monkeypatch):
    """What the representation node and the agent write (``protocol`` file
    names), made here from the offline run of the same configuration."""
    run = run_naive(run_world(cfg), NaiveParams(**cfg["naive"]))
    povs, pairs, set_ids = np.asarray(run.povs), np.asarray(run.pairs), np.asarray(run.set_ids)
    representation = build_representation(povs, pairs, set_ids, cfg, cfg["seed"], processes=1)
    produced = StrategyOutput(povs=povs, pairs=pairs, set_ids=set_ids,
                              true_positions=np.zeros((len(povs), 2)), metrics={}, arrays={},
                              timings_s={})
    arrays = run_files.run_arrays(produced, representation, cfg, cfg["seed"])
    del arrays["true_positions"]                    # the node does not know them
    arrays["agent_changes"] = np.int64(len(run.exploration.kinds))
    arrays["agent_compensated"] = np.int64(run.agent.compensated)
    np.savez(tmp_path / RESULT_FILE, **arrays)
    np.savez(tmp_path / AGENT_RECORDS_FILE, **NaiveAgentRecords.from_agent(run.agent).to_arrays())

    counts = count_world_builds(monkeypatch)
    metrics = graph_run.evaluate_representation(tmp_path, cfg)
    assert metrics["analysis"]["naive_records"].startswith("evaluated by evaluation.naive")
    assert metrics["naive"]["coverage"] > 0.5
    assert counts == {"worlds": 1, "explorations": 1}
