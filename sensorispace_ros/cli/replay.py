"""``sensorispace replay``: republish a recorded bag on its topics (graph.nodes.replay)."""
from __future__ import annotations

import argparse

from sensorispace_ros.cli.arguments import add_bag, checked
from sensorispace_ros.recording.bag_format import BagError

# A bag that is missing, unreadable, truncated or of another schema: one line, exit 2.
USER_ERRORS = (BagError,)


HELP = "republish a recorded bag on its topics"
DESCRIPTION = """
Republish every message of a bag (raw CDR, contract QoS) with its recorded timing scaled
by --rate, or as fast as possible without loss (--fast). Discovery is localhost-only
unless ROS_AUTOMATIC_DISCOVERY_RANGE says otherwise; ROS_DOMAIN_ID selects the graph.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_bag(parser, "bag directory (metadata.yaml + .mcap)")
    speed = parser.add_mutually_exclusive_group()
    speed.add_argument("--rate", type=_rate, default=1.0,
                       help="time scale: 2 replays twice as fast (default 1)")
    speed.add_argument("--fast", action="store_true",
                       help="as fast as possible (reliable, every subscriber matched first)")
    parser.add_argument("--topics", nargs="+", metavar="TOPIC", default=None,
                        help="replay only these topics (default: every topic of the bag)")


_rate = checked(float, lambda value: value > 0, "a positive number")


def run(args: argparse.Namespace) -> int:
    from sensorispace_ros.graph.nodes.replay import replay_bag

    published = replay_bag(args.bag, rate=0.0 if args.fast else args.rate, topics=args.topics)
    print(f"replayed {sum(published.values())} messages from {args.bag}")
    return 0
