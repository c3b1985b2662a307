"""``sensorispace bag``: bag maintenance (``bag verify``: every CRC, counts and
times of a closed bag, recording.bag_verify.verify_bag; ``bag recover``: make the
bag of a killed recorder readable, recording.bag_recovery.recover_bag)."""
from __future__ import annotations

import argparse

from sensorispace_ros.cli.arguments import add_bag
from sensorispace_ros.recording.bag_format import BagError

# A bag that is missing, unreadable, damaged or beyond repair: one line, exit 2.
USER_ERRORS = (BagError,)


HELP = "bag maintenance"
DESCRIPTION = "Bag maintenance commands."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """One action per sub-command, each with its own handler."""
    actions = parser.add_subparsers(dest="bag_command", metavar="ACTION", required=True)
    verify = actions.add_parser(
        "verify", help="check a bag's CRCs, counts and times",
        description="Check every CRC of a closed bag's MCAP (each chunk's, the data "
                    "section's, the summary's), its message indexes, and its message counts "
                    "and times against metadata.yaml and the Statistics record. Exit 0 with a "
                    "one-line summary; exit 2 with one line naming the first problem.")
    add_bag(verify)
    verify.set_defaults(handler=run_verify)
    recover = actions.add_parser(
        "recover", help="make a bag readable after its recorder was killed",
        description="Rebuild metadata.yaml and the MCAP summary of a bag whose recorder "
                    "died (kill -9): every message of every complete chunk whose CRC is right "
                    "is kept, and the write-ahead log's records; a chunk cut short or failing "
                    "its CRC is dropped and named. The damaged file is kept beside it as "
                    "<name>.mcap.truncated.")
    add_bag(recover)
    recover.set_defaults(handler=run_recover)


def run_verify(args: argparse.Namespace) -> int:
    from sensorispace_ros.recording.bag_verify import verify_bag

    print(verify_bag(args.bag).summary())
    return 0


def run_recover(args: argparse.Namespace) -> int:
    from sensorispace_ros.recording.bag_recovery import recover_bag

    report = recover_bag(args.bag)
    print(report.summary())
    return 0
