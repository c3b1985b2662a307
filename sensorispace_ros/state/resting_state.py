"""What the body node persists to survive a restart: its resting motor state and
the number of the last lights applied, in ``<checkpoint_dir>/body.state``
(``RestingStateFile``), and on the row clock where the clock stood
(``body.clock``); ``peek`` reads one without writing (the launcher's progress).
Pure Python + numpy, no rclpy."""
from __future__ import annotations

import os
import struct
import weakref
from pathlib import Path
from typing import Sequence

import numpy as np


def newest(slots: np.ndarray) -> np.ndarray | None:
    """The values of the newest slot whose two sequence numbers agree, or None."""
    valid = [row for row in slots if row[0] > 0 and row[0] == row[-1]]
    return np.array(max(valid, key=lambda row: row[0])[1:-1]) if valid else None


def peek(path: Path) -> np.ndarray | None:
    """The last vector a ``RestingStateFile`` wrote at ``path``, read without
    opening it for writing (its size from the file's); None while it is
    missing or holds nothing valid."""
    try:
        data = np.fromfile(path, dtype=np.float64)
    except (OSError, ValueError):
        return None
    if len(data) < 6 or len(data) % 2:
        return None
    return newest(data.reshape(2, -1))


class RestingStateFile:
    """A short float vector in a small file of native float64s.

    Two slots written alternately, each ``[seq, values..., seq]``: a kill -9 in the
    middle of a write leaves the slot's two sequence numbers unequal, and
    ``load`` takes the newest slot whose numbers agree (seqlock). No fsync, no
    rename: the page cache keeps what a killed process wrote (a machine crash
    is out of scope). ``slots`` maps the file (what ``load`` reads); ``save``
    writes a slot with one ``os.pwrite`` of its packed bytes, in the page cache
    when it returns, and cheaper a command than stores through the mapping.
    """

    def __init__(self, path: Path, size: int):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        shape = (2, size + 2)
        fresh = not self.path.is_file() or self.path.stat().st_size != 8 * shape[0] * shape[1]
        self.slots = np.memmap(self.path, dtype=np.float64, mode="w+" if fresh else "r+",
                               shape=shape)
        self.size = size
        self._slot = struct.Struct(f"={shape[1]}d")      # one row of ``slots``, same bytes
        self._fd = os.open(self.path, os.O_RDWR)
        weakref.finalize(self, os.close, self._fd)
        self.seq = int(max((row[0] for row in self._valid_slots()), default=0))

    def _valid_slots(self) -> list[np.ndarray]:
        return [row for row in self.slots if row[0] > 0 and row[0] == row[-1]]

    def load(self) -> np.ndarray | None:
        """The last vector written, or None (no file, nothing valid)."""
        return newest(self.slots)

    def save(self, values: Sequence[float]) -> None:
        """Write ``values`` (``size`` numbers) over the older slot."""
        seq = self.seq + 1
        try:
            data = self._slot.pack(seq, *values, seq)
        except struct.error as exc:
            raise ValueError(f"values: {self.size} numbers expected ({exc})") from None
        if os.pwrite(self._fd, data, (seq % 2) * self._slot.size) != len(data):
            raise OSError(f"{self.path}: short write")
        self.seq = seq
