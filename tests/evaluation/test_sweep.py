"""Sweeps on real Dask clusters: same numbers as ``reproduce``, survives a killed
worker, resumes after an interruption; and on a scheduler with separate workers."""
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from sensorispace_ros import config as config_mod
from sensorispace_ros.evaluation.reproduce import reproduce
from sensorispace_ros.evaluation.run_files import METRICS_FILE, flatten_metrics
from sensorispace_ros.evaluation.sweep import (PARTIAL_PREFIX, connect, parse_seeds, plan_sweep,
                                            run_sweep, sweep)
from sensorispace_ros.evaluation.sweep_summary import SUMMARY_JSON, SUMMARY_MD

from shared import SMOKE, free_port, stop_by_pid

pytestmark = pytest.mark.slow

SEEDS = [0, 1, 2, 3]
BIN = Path(sys.executable).parent


def _results(path: Path) -> dict:
    """A run's metrics without its wall times (the only thing allowed to differ)."""
    flat = flatten_metrics(json.loads(Path(path).read_text()))
    return {k: v for k, v in flat.items()
            if not any(f"{part}." in f".{k}" for part in (".timings_s", ".seconds_by_stage"))}


@pytest.fixture(scope="module")
def reference(tmp_path_factory, smoke_naive_reference):
    """``reproduce`` of every smoke seed and strategy, in this process (the naive
    run of smoke.yaml's own seed is the session's)."""
    root = tmp_path_factory.mktemp("reference")
    smoke_seed = config_mod.load_config(SMOKE)["seed"]
    out = {}
    for strategy in ("paper", "naive"):
        for seed in SEEDS:
            run_dir = root / f"{strategy}-{seed}"
            if (strategy, seed) == ("naive", smoke_seed):
                run_dir = smoke_naive_reference.run_dir
            else:
                cfg = config_mod.load_config(SMOKE, {"seed": seed, "output.figures": False})
                reproduce(cfg, strategy, out_dir=run_dir)
            out[strategy, seed] = _results(run_dir / METRICS_FILE)
    return out


def test_seed_lists_parse_as_ranges_and_lists():
    assert parse_seeds("0-3") == [0, 1, 2, 3]
    assert parse_seeds("5") == [5]
    assert parse_seeds("0-1,7,3-4") == [0, 1, 3, 4, 7]
    with pytest.raises(ValueError, match="--seeds"):
        parse_seeds("3-1")
    with pytest.raises(ValueError, match="--seeds"):
        parse_seeds("a")


@pytest.mark.parametrize("strategy", ["paper", "naive"])
def test_a_local_sweep_with_a_killed_worker_gives_reproduce_s_numbers(strategy, reference,
                                                                      tmp_path):
    tasks = plan_sweep([SMOKE], strategy, SEEDS, tmp_path)
    killed = []

    with connect(workers=2) as client:
        def kill_a_busy_worker(line):
            if killed:
                return
            busy = [addr for addr, keys in client.processing().items() if keys]
            if busy:
                pid = client.run(os.getpid, workers=busy[:1])[busy[0]]
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)

        outcome = run_sweep(tasks, client, report=kill_a_busy_worker)
    assert killed, "no worker was busy after the first task: the kill was not exercised"
    assert not outcome.failed
    assert sorted(t.seed for t in outcome.done) == SEEDS
    for task in tasks:
        assert _results(Path(task.run_dir) / METRICS_FILE) == reference[strategy, task.seed]
    assert not list(tmp_path.rglob(f"{PARTIAL_PREFIX}*"))


def test_a_second_invocation_finishes_only_the_missing_runs(reference, tmp_path):
    tasks = plan_sweep([SMOKE], "paper", SEEDS, tmp_path)

    class Interrupted(Exception):
        pass

    def interrupt_at_the_first_result(line):
        raise Interrupted

    # Stopped after one run of the first two; the last two were never started
    # (a fast machine may finish every submitted run before the stop arrives).
    with pytest.raises(Interrupted):
        with connect(workers=2) as client:
            run_sweep(tasks[:2], client, report=interrupt_at_the_first_result)
    complete = [t for t in tasks if (Path(t.run_dir) / METRICS_FILE).is_file()]
    missing = [t for t in tasks if t not in complete]
    assert complete and missing
    # A run torn by a kill -9 leaves only its private partial directory.
    torn = Path(missing[0].run_dir).parent / f"{PARTIAL_PREFIX}seed-{missing[0].seed}-deadbeef"
    torn.mkdir(parents=True, exist_ok=True)
    (torn / "arrays.npz").write_bytes(b"torn")
    stamps = {t.seed: (Path(t.run_dir) / METRICS_FILE).stat().st_mtime_ns for t in complete}

    outcome = sweep([SMOKE], "paper", SEEDS, tmp_path, workers=2)
    assert sorted(t.seed for t in outcome.skipped) == sorted(stamps)
    assert sorted(t.seed for t in outcome.done) == sorted(set(SEEDS) - set(stamps))
    for task in tasks:
        metrics = Path(task.run_dir) / METRICS_FILE
        assert _results(metrics) == reference["paper", task.seed]
        if task.seed in stamps:
            assert metrics.stat().st_mtime_ns == stamps[task.seed]
    assert not torn.exists()

    summary = json.loads((tmp_path / SUMMARY_JSON).read_text())["configs"]["smoke"]
    assert summary["seeds"] == SEEDS
    compensated = [reference["paper", s]["exploration.compensated"] for s in SEEDS]
    entry = summary["metrics"]["exploration.compensated"]
    assert entry["min"] == min(compensated) and entry["max"] == max(compensated)
    assert entry["mean"] == pytest.approx(sum(compensated) / len(compensated))
    assert compensated[SEEDS.index(entry["seed_max"])] == max(compensated)
    assert "`exploration.compensated`" in (tmp_path / SUMMARY_MD).read_text()


def _stop(processes):
    for process in processes:
        stop_by_pid(process)


def test_a_sweep_on_a_scheduler_with_two_separate_workers(reference, tmp_path):
    address = f"tcp://127.0.0.1:{free_port()}"
    port = address.rsplit(":", 1)[1]
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
    log = (tmp_path / "dask.log").open("w")
    processes = [subprocess.Popen([str(BIN / "dask"), "scheduler", "--host", "127.0.0.1",
                                   "--port", port, "--no-dashboard"],
                                  stdout=log, stderr=subprocess.STDOUT, env=env)]
    try:
        for _ in range(2):
            processes.append(subprocess.Popen(
                [str(BIN / "dask"), "worker", address, "--nthreads", "1", "--host",
                 "127.0.0.1", "--no-dashboard"], stdout=log, stderr=subprocess.STDOUT, env=env))
        from distributed import Client
        with Client(address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=60)
        outcome = sweep([SMOKE], "naive", SEEDS, tmp_path / "out", scheduler=address)
    finally:
        _stop(processes)
        log.close()
    assert not outcome.failed and len(outcome.done) == len(SEEDS)
    for task in outcome.done:
        assert _results(Path(task.run_dir) / METRICS_FILE) == reference["naive", task.seed]
    assert all(p.returncode is not None for p in processes)


def test_a_misleading_metric_is_explained_under_its_table():
    from sensorispace_ros.evaluation.sweep_summary import summary_markdown

    def summary(keys):
        stats = {"mean": 0.1, "sd": 0.0, "min": 0.0015, "max": 1.0, "seed_min": 0, "seed_max": 1}
        return {"strategy": "naive",
                "configs": {"paper": {"seeds": [0, 1], "metrics": {k: stats for k in keys}}}}

    shown = summary_markdown(summary(["naive.coverage", "naive.coverage_of_paper_positions"]))
    assert "`naive.coverage_of_paper_positions`: the fraction of the paper strategy's" in shown
    assert "lattice offset" not in summary_markdown(summary(["naive.coverage"]))
