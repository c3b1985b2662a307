"""``sensorispace reproduce``: run a strategy offline, write metrics.json and figures."""
from __future__ import annotations

import argparse

from sensorispace_ros.cli.arguments import add_out, checked, out_dir
from sensorispace_ros.cli.summary import summary_table


HELP = "run a strategy offline; write metrics.json, arrays.npz and figures"
DESCRIPTION = """
Run the paper's two simulations with one strategy and write DIR/metrics.json,
DIR/arrays.npz and DIR/figures/*.png.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--strategy", choices=("paper", "naive"), default="paper",
                        help="paper: analytic shortcuts; naive: sensorimotor flow only "
                             "(default: paper)")
    parser.add_argument("--seed", type=_seed, default=None,
                        help="seed of every random choice (default: the config's seed)")
    add_out(parser, "output directory (default: results/<strategy>-seed<S>)")
    parser.add_argument("--config", metavar="FILE", default=None,
                        help="parameter file (default: the paper's values, "
                             "as in config/paper.yaml)")
    parser.add_argument("--no-figures", action="store_true", help="skip the figures")
    parser.add_argument("--quiet", action="store_true", help="no progress display")


_seed = checked(int, lambda value: value >= 0, "a non-negative integer")


def run(args: argparse.Namespace) -> int:
    from sensorispace_ros import config as config_mod
    from sensorispace_ros.evaluation.reproduce import reproduce
    from sensorispace_ros.progress import Progress

    overrides = {}
    if args.seed is not None:
        overrides["seed"] = args.seed
    if args.no_figures:
        overrides["output.figures"] = False
    cfg = config_mod.load_config(args.config, overrides)
    out = out_dir(args, f"{args.strategy}-seed{cfg['seed']}")
    progress = Progress(enabled=not args.quiet)
    metrics = reproduce(cfg, args.strategy, out_dir=out, progress=progress,
                        figures=not args.no_figures)
    print(summary_table(metrics, out))
    return 0
