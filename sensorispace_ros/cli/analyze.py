"""``sensorispace analyze``: a run's representation and metrics rebuilt from its bag
alone (evaluation.analyze.analyze_bag)."""
from __future__ import annotations

import argparse
from pathlib import Path

from sensorispace_ros.cli.arguments import add_bag, add_out, out_dir
from sensorispace_ros.cli.summary import summary_table
from sensorispace_ros.recording.bag_format import BagError

# A bag that is missing, unreadable, truncated or of another schema: one line, exit 2.
USER_ERRORS = (BagError,)


HELP = "rebuild a run's representation and metrics from its bag"
DESCRIPTION = """
Rebuild points of view, metric, embeddings and reaching from a bag alone (configuration
and seed are stored in it), join the recorded ground truth and write DIR/metrics.json,
arrays.npz and figures.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_bag(parser)
    add_out(parser, "output directory (default: results/<bag name>-analyzed)")


def run(args: argparse.Namespace) -> int:
    from sensorispace_ros.evaluation import analyze

    bag = Path(args.bag)
    out = out_dir(args, f"{bag.resolve().name}-analyzed")
    metrics = analyze.analyze_bag(bag, out)
    print(summary_table(metrics, out))
    return 0
