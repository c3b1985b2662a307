"""Run ``sensorispace`` in this process with counters wrapped around the
agent's methods (``bench/clock_rows.py``, ``bench/clock_drift.py``): the
script's own arguments are the command's; ``instrument()`` runs first and
``write(out)`` at exit, ``out`` the run's ``--out`` directory."""
from __future__ import annotations

import atexit
import sys
from pathlib import Path


def run_instrumented(instrument, write) -> None:
    from sensorispace_ros.cli.main import main as cli

    out = Path(sys.argv[sys.argv.index("--out") + 1])
    atexit.register(write, out)
    instrument()
    sys.argv = ["sensorispace"] + sys.argv[1:]
    cli()
