"""How a sweep scales with local Dask workers.

Runs the same sweep (default: 8 naive seeds of config/paper.yaml) through
``sensorispace_ros.evaluation.sweep.sweep`` on a LocalCluster of 1 worker, then
of 2 workers, each into a fresh directory, and prints:

- the wall time of each and their ratio (2 workers / 1 worker);
- the per-task overhead: (wall time on 1 worker - the sum of the runs' own
  ``timings_s.total``) / number of tasks, i.e. what Dask, process start-up
  and the file moves add to each run.

    python bench/sweep_scaling.py                       # 8 naive seeds, paper config
    python bench/sweep_scaling.py --seeds 0-3 --config config/smoke.yaml
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from sensorispace_ros.evaluation.run_files import METRICS_FILE  # noqa: E402
from sensorispace_ros.evaluation.sweep import parse_seeds, sweep  # noqa: E402


def timed_sweep(config: Path, strategy: str, seeds: list[int], workers: int,
                out: Path) -> dict:
    started = time.perf_counter()
    outcome = sweep([config], strategy, seeds, out, workers=workers)
    wall = time.perf_counter() - started
    if outcome.failed:
        raise SystemExit(f"sweep failed: {outcome.failed}")
    own = sum(json.loads((Path(t.run_dir) / METRICS_FILE).read_text())["timings_s"]["total"]
              for t in outcome.done)
    return {"workers": workers, "wall_s": wall, "runs_total_s": own, "tasks": len(seeds)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", type=Path, default=REPO / "config" / "paper.yaml")
    parser.add_argument("--strategy", default="naive", choices=("paper", "naive"))
    parser.add_argument("--seeds", default="0-7")
    args = parser.parse_args(argv)
    seeds = parse_seeds(args.seeds)
    with tempfile.TemporaryDirectory() as tmp:
        one = timed_sweep(args.config, args.strategy, seeds, 1, Path(tmp) / "one")
        two = timed_sweep(args.config, args.strategy, seeds, 2, Path(tmp) / "two")
    overhead = (one["wall_s"] - one["runs_total_s"]) / one["tasks"]
    print(f"1 worker : {one['wall_s']:.1f} s wall, runs' own time {one['runs_total_s']:.1f} s")
    print(f"2 workers: {two['wall_s']:.1f} s wall, runs' own time {two['runs_total_s']:.1f} s")
    print(f"ratio 2 workers / 1 worker: {two['wall_s'] / one['wall_s']:.3f}")
    print(f"per-task overhead on 1 worker: {overhead:.2f} s")
    print(json.dumps({"one": one, "two": two, "ratio": two["wall_s"] / one["wall_s"],
                      "per_task_overhead_s": overhead}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
