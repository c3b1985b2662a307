"""``sensorispace replay | analyze | bag recover``: the bag subcommands.

``register(subparsers)`` is called by cli.py. Bag problems (missing,
unreadable, truncated, another schema) raise ``bags.BagError``, listed in
``USER_ERRORS``, so the command prints one line and exits 2.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from sensorispace_ros.recording.bags import BagError

USER_ERRORS = (BagError,)


def _rate(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return value


def register(subparsers) -> None:
    replay = subparsers.add_parser(
        "replay", help="republish a recorded bag on its topics",
        description="Republish every message of a bag (raw CDR, contract QoS) with its "
                    "recorded timing scaled by --rate, or as fast as possible without loss "
                    "(--fast). Discovery is localhost-only unless ROS_AUTOMATIC_DISCOVERY_RANGE "
                    "says otherwise; ROS_DOMAIN_ID selects the graph.")
    replay.add_argument("bag", metavar="BAG", help="bag directory (metadata.yaml + .mcap)")
    speed = replay.add_mutually_exclusive_group()
    speed.add_argument("--rate", type=_rate, default=1.0,
                       help="time scale: 2 replays twice as fast (default 1)")
    speed.add_argument("--fast", action="store_true",
                       help="as fast as possible (reliable, every subscriber matched first)")
    replay.add_argument("--topics", nargs="+", metavar="TOPIC", default=None,
                        help="replay only these topics (default: every topic of the bag)")
    replay.set_defaults(handler=run_replay)

    analyze = subparsers.add_parser(
        "analyze", help="rebuild a run's representation and metrics from its bag",
        description="Rebuild points of view, metric, embeddings and reaching from a bag "
                    "alone (configuration and seed are stored in it), join the recorded "
                    "ground truth and write DIR/metrics.json, arrays.npz and figures.")
    analyze.add_argument("bag", metavar="BAG", help="bag directory")
    analyze.add_argument("--out", metavar="DIR", default=None,
                         help="output directory (default: results/<bag name>-analyzed)")
    analyze.set_defaults(handler=run_analyze)

    bag = subparsers.add_parser("bag", help="bag maintenance",
                                description="Bag maintenance commands.")
    bag_sub = bag.add_subparsers(dest="bag_command", metavar="ACTION", required=True)
    recover = bag_sub.add_parser(
        "recover", help="make a bag readable after its recorder was killed",
        description="Rebuild metadata.yaml and the MCAP summary of a bag whose recorder "
                    "died (kill -9): every message of every complete chunk is kept; the "
                    "damaged file is kept beside it as <name>.mcap.truncated.")
    recover.add_argument("bag", metavar="BAG", help="bag directory")
    recover.set_defaults(handler=run_recover)


def run_replay(args: argparse.Namespace) -> int:
    from sensorispace_ros.graph.nodes.replay import replay_bag

    published = replay_bag(args.bag, rate=0.0 if args.fast else args.rate, topics=args.topics)
    print(f"replayed {sum(published.values())} messages from {args.bag}")
    return 0


def run_analyze(args: argparse.Namespace) -> int:
    from sensorispace_ros.recording import analyze

    bag = Path(args.bag)
    out = Path(args.out) if args.out else Path("results") / f"{bag.resolve().name}-analyzed"
    metrics = analyze.analyze_bag(bag, out)
    try:
        from sensorispace_ros.cli.main import summary_table

        print(summary_table(metrics, out))
    except ImportError:
        print(f"metrics written to {out / 'metrics.json'}")
    return 0


def run_recover(args: argparse.Namespace) -> int:
    from sensorispace_ros.recording.bags import recover_bag

    report = recover_bag(args.bag)
    print(report.summary())
    return 0
