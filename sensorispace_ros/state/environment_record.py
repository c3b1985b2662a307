"""The environment node's progress record, ``<checkpoint_dir>/environment.json``.

One fixed-size JSON record ``{"current": k, "settled": s}`` overwritten in
place at every change (one ``pwrite``). The environment reads it back after
a restart; the launcher polls it to show the run's progress. A
file instead of a subscription to ``/agent/settled``: a subscriber in the
launcher woke its process (a DDS thread and a Python executor) at every
change, inside the hand-over the agent waits for.

No rclpy here: the launcher imports it.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

from sensorispace_ros.protocol import PROGRESS_FILE  # noqa: F401 (the record's file)

# Well inside a page: one pwrite replaces the whole record. Always this many
# bytes (JSON ignores the trailing blanks), so a shorter record never leaves
# the tail of a longer one behind.
PROGRESS_BYTES = 64


def encode_progress(current: int, settled: int) -> bytes:
    record = json.dumps({"current": int(current), "settled": int(settled)}).encode()
    if len(record) > PROGRESS_BYTES:
        raise ValueError(f"progress record of {len(record)} bytes > {PROGRESS_BYTES}")
    return record.ljust(PROGRESS_BYTES)


def decode_progress(data: bytes) -> tuple[int, int]:
    """``(current, settled)``; ValueError (naming the problem) if ``data`` is
    not a progress record."""
    try:
        record = json.loads(data)
        current, settled = int(record["current"]), int(record["settled"])
    except (ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"not a progress record ({type(exc).__name__}: {exc})") from exc
    return current, settled


def read_progress(path: str | Path) -> tuple[int, int] | None:
    """``(current, settled)`` from ``path``, or None while it is missing or
    unreadable (not written yet, or read in the middle of a write: the
    launcher only shows it)."""
    try:
        with open(path, "rb") as f:
            return decode_progress(f.read(PROGRESS_BYTES))
    except (OSError, ValueError):
        return None


class ProgressWriter:
    """Overwrites ``path`` with each record (the file is opened once)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._fd: int | None = None

    def write(self, current: int, settled: int) -> None:
        if self._fd is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT, 0o644)
        os.pwrite(self._fd, encode_progress(current, settled), 0)

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
