"""``sensorispace sweep``: many seeds and configurations, placed by Dask."""
from __future__ import annotations

import argparse
import sys
from sensorispace_ros.cli.arguments import add_out, out_dir
from sensorispace_ros.evaluation.sweep import SweepError, parse_seeds


HELP = "run every (config, seed) as a Dask task; summarise the spread"
DESCRIPTION = """
Run a strategy for every configuration and seed through dask.distributed (a LocalCluster
by default, or --scheduler), writing DIR/<config-name>/seed-<k>/ and DIR/summary.json,
DIR/summary.md. A rerun skips the complete runs and redoes the torn ones.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--strategy", choices=("paper", "naive"), required=True)
    parser.add_argument("--config", metavar="FILE", nargs="+", required=True,
                        help="parameter files (each is a directory of the sweep)")
    parser.add_argument("--seeds", type=_seeds, required=True,
                        help="seeds, e.g. 0-31 or 0,3,5")
    add_out(parser, "sweep directory (default: results/sweep-<strategy>)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None,
                       help="local worker processes (default: one per core)")
    where.add_argument("--scheduler", metavar="tcp://HOST:PORT", default=None,
                       help="an existing Dask scheduler instead of a local cluster")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


USER_ERRORS = (SweepError,)


def _seeds(text: str) -> list[int]:
    try:
        return parse_seeds(text)
    except SweepError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    from sensorispace_ros.evaluation.sweep import sweep

    out = out_dir(args, f"sweep-{args.strategy}")
    report = None if args.quiet else (lambda line: print(line, file=sys.stderr, flush=True))
    outcome = sweep(args.config, args.strategy, args.seeds, out, workers=args.workers,
                    scheduler=args.scheduler, report=report)
    print(f"sweep: {len(outcome.done)} run, {len(outcome.skipped)} already complete, "
          f"{len(outcome.failed)} failed; summary in {out / 'summary.md'}")
    for task, why in outcome.failed:
        print(f"sweep: failed: {task.label} ({task.config_path}): {why}", file=sys.stderr)
    return 1 if outcome.failed else 0
