"""``sensorispace bag``: bag maintenance (``bag recover``: make the bag of a killed
recorder readable, recording.bag_recovery.recover_bag)."""
from __future__ import annotations

import argparse

from sensorispace_ros.recording.bag_format import BagError

# A bag that is missing, unreadable or beyond repair: one line, exit 2.
USER_ERRORS = (BagError,)


def register(subparsers) -> None:
    bag = subparsers.add_parser("bag", help="bag maintenance",
                                description="Bag maintenance commands.")
    actions = bag.add_subparsers(dest="bag_command", metavar="ACTION", required=True)
    recover = actions.add_parser(
        "recover", help="make a bag readable after its recorder was killed",
        description="Rebuild metadata.yaml and the MCAP summary of a bag whose recorder "
                    "died (kill -9): every message of every complete chunk is kept; the "
                    "damaged file is kept beside it as <name>.mcap.truncated.")
    recover.add_argument("bag", metavar="BAG", help="bag directory")
    recover.set_defaults(handler=run_recover)


def run_recover(args: argparse.Namespace) -> int:
    from sensorispace_ros.recording.bag_recovery import recover_bag

    report = recover_bag(args.bag)
    print(report.summary())
    return 0
