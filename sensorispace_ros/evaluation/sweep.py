"""Studies over many seeds and configurations, placed by ``dask.distributed``.

Every (configuration, seed) pair is one task that runs ``reproduce`` with
figures off and writes the usual run directory under
``<out>/<config-name>/seed-<k>/``. Dask only places the work: each random
choice still comes from the seed, so a task's ``metrics.json`` equals the one
``sensorispace reproduce`` writes for the same configuration and seed
(timings aside).

A run is written into a private ``.partial-*`` directory and renamed into
place when it is complete, so a run directory exists only once it is whole.
A second invocation therefore skips the complete runs and redoes the torn
ones; a task that Dask re-runs after losing its worker cannot mix its files
with those of the first attempt.

Without ``scheduler`` a ``LocalCluster`` runs one single-threaded worker
process per core (or ``workers``); with it, the tasks go to an existing
scheduler (``dask scheduler`` + ``dask worker tcp://...`` on each host).
"""
from __future__ import annotations

import os
import re
import shutil
import time
import uuid
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Iterator, Sequence

from sensorispace_ros.evaluation.run_files import METRICS_FILE

STRATEGIES = ("paper", "naive")
SEED_DIR = "seed-{seed}"
PARTIAL_PREFIX = ".partial-"
_SEED_RANGE = re.compile(r"^(\d+)(?:-(\d+))?$")


class SweepError(ValueError):
    """A sweep's arguments are unusable (unknown strategy, bad seed list...)."""


@dataclass(frozen=True)
class SweepTask:
    """One run of a sweep: which configuration, strategy and seed, and where."""

    config_path: str
    config_name: str
    strategy: str
    seed: int
    run_dir: str

    @property
    def label(self) -> str:
        return f"{self.config_name} seed {self.seed}"


@dataclass
class SweepOutcome:
    """What a sweep did: runs skipped (already complete), done, and failed."""

    skipped: list[SweepTask]
    done: list[SweepTask]
    failed: list[tuple[SweepTask, str]]


def parse_seeds(text: str) -> list[int]:
    """``"0-31"``, ``"3"`` or ``"0-3,8,10-11"`` as a sorted list of seeds."""
    seeds: set[int] = set()
    for part in text.split(","):
        match = _SEED_RANGE.match(part.strip())
        if not match:
            raise SweepError(f"--seeds: expected e.g. 0-31 or 0,3,5, got {text!r}")
        first = int(match.group(1))
        last = int(match.group(2)) if match.group(2) is not None else first
        if last < first:
            raise SweepError(f"--seeds: range {part.strip()!r} runs backwards")
        seeds.update(range(first, last + 1))
    return sorted(seeds)


def config_name(path: str | Path) -> str:
    """A configuration's name in the sweep's tree: its file name without suffix."""
    return Path(path).stem


def plan_sweep(config_paths: Sequence[str | Path], strategy: str, seeds: Iterable[int],
               out_dir: str | Path) -> list[SweepTask]:
    """Every (configuration, seed) task, each validated configuration first."""
    from sensorispace_ros import config as config_mod

    if strategy not in STRATEGIES:
        raise SweepError(f"--strategy: must be one of {', '.join(STRATEGIES)}, got {strategy!r}")
    names = [config_name(p) for p in config_paths]
    if len(set(names)) != len(names):
        raise SweepError(f"--config: two files share a name: {', '.join(names)}")
    for path in config_paths:
        config_mod.load_config(path)           # a bad file fails before any task runs
    out_dir = Path(out_dir)
    return [SweepTask(str(Path(path).resolve()), name, strategy, seed,
                      str(out_dir / name / SEED_DIR.format(seed=seed)))
            for path, name in zip(config_paths, names) for seed in seeds]


def is_complete(task: SweepTask) -> bool:
    """A run directory exists only once it is whole (see ``run_task``)."""
    return (Path(task.run_dir) / METRICS_FILE).is_file()


def run_task(task: SweepTask) -> str:
    """Run one task (on a worker) and move its directory into place.

    Returns the run directory. Any partial directory of an earlier, torn
    attempt of the same run is removed once this one is in place.
    """
    from sensorispace_ros import config as config_mod
    from sensorispace_ros.evaluation.reproduce import reproduce

    final = Path(task.run_dir)
    if is_complete(task):
        return str(final)
    final.parent.mkdir(parents=True, exist_ok=True)
    partial = final.parent / f"{PARTIAL_PREFIX}{final.name}-{uuid.uuid4().hex[:8]}"
    cfg = config_mod.load_config(task.config_path, {"seed": task.seed})
    reproduce(cfg, task.strategy, out_dir=partial, progress=None, figures=False)
    try:
        os.rename(partial, final)
    except OSError:
        if not is_complete(task):             # not another attempt's whole run: a real error
            raise
        shutil.rmtree(partial, ignore_errors=True)
    _remove_partials(final)
    return str(final)


def _remove_partials(final: Path) -> None:
    for stale in final.parent.glob(f"{PARTIAL_PREFIX}{final.name}-*"):
        shutil.rmtree(stale, ignore_errors=True)


def _worker_count(workers: int | None) -> int:
    if workers is None:
        return max(1, os.cpu_count() or 1)
    if workers < 1:
        raise SweepError(f"--workers: must be an integer >= 1, got {workers}")
    return workers


@contextmanager
def connect(workers: int | None = None, scheduler: str | None = None) -> Iterator:
    """A ``distributed.Client`` on a new ``LocalCluster``, or on ``scheduler``."""
    import dask
    from distributed import Client, LocalCluster

    if scheduler is not None:
        with Client(scheduler, timeout="30s") as client:
            yield client
        return
    # One single-threaded process per worker: the runs are CPU-bound Python.
    # Not daemons, so that a run may start processes of its own.
    with dask.config.set({"distributed.worker.daemon": False}):
        with LocalCluster(n_workers=_worker_count(workers), threads_per_worker=1,
                          processes=True, dashboard_address=None, host="127.0.0.1") as cluster:
            with Client(cluster) as client:
                yield client


def sweep(config_paths: Sequence[str | Path], strategy: str, seeds: Iterable[int],
          out_dir: str | Path, workers: int | None = None, scheduler: str | None = None,
          report: Callable[[str], None] | None = None) -> SweepOutcome:
    """Plan, run and summarise a sweep; see the module docstring."""
    from sensorispace_ros.evaluation.sweep_summary import summarize

    tasks = plan_sweep(config_paths, strategy, list(seeds), out_dir)
    with connect(workers, scheduler) as client:
        outcome = run_sweep(tasks, client, report)
    runs: dict[str, dict[int, Path]] = {}
    for task in tasks:
        runs.setdefault(task.config_name, {})[task.seed] = Path(task.run_dir)
    summarize(out_dir, runs, strategy)
    return outcome


def run_sweep(tasks: Sequence[SweepTask], client, report: Callable[[str], None] | None = None,
              retries: int = 2) -> SweepOutcome:
    """Submit the incomplete tasks to ``client``; wait for all; never stop at a failure.

    ``report`` gets a progress line after each finished task. A task whose
    worker died is rescheduled by Dask (``retries`` more times if it raised).
    """
    from distributed import as_completed

    skipped = [t for t in tasks if is_complete(t)]
    todo = [t for t in tasks if not is_complete(t)]
    outcome = SweepOutcome(skipped=skipped, done=[], failed=[])
    futures = {client.submit(run_task, task, key=f"sweep-{task.config_name}-{task.strategy}-"
                             f"{task.seed}-{uuid.uuid4().hex[:6]}", retries=retries,
                             pure=False): task
               for task in todo}
    started = time.monotonic()
    for future in as_completed(futures):
        task = futures[future]
        try:
            future.result()
            outcome.done.append(task)
        except Exception as exc:                # the task's own error, named with its run
            outcome.failed.append((task, f"{type(exc).__name__}: {exc}"))
        if report is not None:
            running = _running(client)
            report(progress_line(len(outcome.done), running, len(outcome.failed), len(todo),
                                 time.monotonic() - started, outcome.failed))
    return outcome


def _running(client) -> int:
    """Tasks executing now: a worker may hold more than it has threads."""
    threads = client.nthreads()
    return sum(min(len(keys), threads.get(worker, 1))
               for worker, keys in client.processing().items())


def progress_line(done: int, running: int, failed: int, total: int, elapsed_s: float,
                  failures: Sequence[tuple[SweepTask, str]] = ()) -> str:
    """``sweep: 12/64 done, 2 running, 1 failed, ~3m10s left`` plus the last failure."""
    from sensorispace_ros.progress import format_seconds

    finished = done + failed
    left = total - finished
    line = f"sweep: {done}/{total} done, {running} running, {failed} failed"
    if finished and left:
        line += f", ~{format_seconds(elapsed_s / finished * left)} left"
    if failures and failed:
        task, why = failures[-1]
        line += f" (failed: {task.label}: {why})"
    return line
