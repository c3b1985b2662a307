"""Arguments that several ``sensorispace`` verbs take, and checked argument types."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Callable, TypeVar

T = TypeVar("T")


def add_bag(parser: argparse.ArgumentParser, help: str = "bag directory") -> None:
    """The positional BAG: a bag directory."""
    parser.add_argument("bag", metavar="BAG", help=help)


def add_out(parser: argparse.ArgumentParser, help: str) -> None:
    """``--out DIR``, resolved by ``out_dir``."""
    parser.add_argument("--out", metavar="DIR", default=None, help=help)


def out_dir(args: argparse.Namespace, default_name: str) -> Path:
    """``--out``, or ``results/<default_name>`` without it."""
    return Path(args.out) if args.out else Path("results") / default_name


def checked(convert: Callable[[str], T], accept: Callable[[T], bool],
            requirement: str) -> Callable[[str], T]:
    """An argparse ``type``: ``convert`` the text, and refuse it unless ``accept``
    holds ("must be <requirement>, got '<text>'")."""
    def parse(text: str) -> T:
        try:
            value = convert(text)
        except ValueError:
            value = None
        if value is None or not accept(value):
            raise argparse.ArgumentTypeError(f"must be {requirement}, got {text!r}")
        return value
    return parse
