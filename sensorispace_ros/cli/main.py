"""The ``sensorispace`` command: the parser of every verb, and how it ends.

Each verb is a module of this package named after it (``VERBS``): ``HELP`` and
``DESCRIPTION`` (its help line and its ``--help`` text), ``add_arguments(parser)``
and ``run(args) -> int``, the exit status (a verb with actions, such as ``bag``,
sets a handler per action instead). A module may list, in ``USER_ERRORS``,
exception types beyond ValueError and OSError that are the user's to fix.

A user error (bad configuration, missing file, unreadable bag) prints one line
``sensorispace: error: ...`` and exits 2; ``SENSORISPACE_DEBUG=1`` shows the
traceback instead. Ctrl-C exits 130.
"""
from __future__ import annotations

import argparse
import os
import sys
from typing import Sequence

from sensorispace_ros.cli import analyze, bag, compare, launch, replay, reproduce, sweep

PROG = "sensorispace"
VERBS = (reproduce, compare, launch, analyze, replay, bag, sweep)
EXIT_USER_ERROR = 2
EXIT_INTERRUPTED = 130


def build_parser() -> tuple[argparse.ArgumentParser, tuple[type[BaseException], ...]]:
    """The command's parser and the exception types its verbs report as user errors."""
    parser = argparse.ArgumentParser(
        prog=PROG, description="Discovering space: a naive agent's sensorimotor pipeline.")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    user_errors: list[type[BaseException]] = [ValueError, OSError]
    for verb in VERBS:
        verb_parser = subparsers.add_parser(verb.__name__.rpartition(".")[2], help=verb.HELP,
                                            description=verb.DESCRIPTION)
        verb.add_arguments(verb_parser)
        if hasattr(verb, "run"):
            verb_parser.set_defaults(handler=verb.run)
        user_errors += [e for e in getattr(verb, "USER_ERRORS", ()) if e not in user_errors]
    return parser, tuple(user_errors)


def main(argv: Sequence[str] | None = None) -> int:
    parser, user_errors = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except user_errors as exc:
        if os.environ.get("SENSORISPACE_DEBUG"):
            raise
        print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_USER_ERROR


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        return f"{exc.filename}: {exc.strerror}"
    text = " ".join(str(exc).split())
    return text or type(exc).__name__
