"""What the body node knew of time in a world on its own clock, written when
the run is over (``<checkpoint_dir>/body.truth.npz``) so that a launched run
is evaluated as an offline one (``evaluation.graph_clock``): the rows executed
after each command (row clock) and the world state each was answered in; on
the row clock also the clock's end, its held rows and how far each change
moved the sensation at the resting arm. Never read by the agent. The body
also appends each command's record as it answers (``TruthLog``,
``body.truth.log``), so that a body restarted after a kill -9 knows what the
dead one knew (``graph.nodes.body_clock``); a restarted body without that log
says its record is not ``whole``. Also the layout of
``body.clock`` (a ``RestingStateFile``): the last command's number and where
the clock stood before and after it (``clock_record``, ``split_clock_record``).
Pure numpy, no rclpy."""
from __future__ import annotations

import os
import weakref
from pathlib import Path

import numpy as np


def clock_record(number: int, before: np.ndarray, after: np.ndarray) -> tuple:
    """``body.clock``'s vector: command ``number`` and the clock's positions
    (``core.world_clock.ClockedBody.position``) before and after it."""
    return (number, *before, *after)


def split_clock_record(values: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """``(number, before, after)`` of a ``clock_record`` vector."""
    before, after = np.split(np.asarray(values, dtype=float)[1:], 2)
    return int(values[0]), before, after


class TruthLog:
    """The body's record of time, appended command by command: records of
    three float64s, ``(number, rows after it, world state after it)`` for a
    command or hold, ``(-1 - k, how far change k moved the resting
    sensation, 0)`` for a change. One ``os.write`` a record on an append-only
    descriptor: in the page cache when it returns, so a kill -9 loses none
    that was answered (the answer is published after it); a record cut by
    the kill is ignored on reading. Written again for a command executed
    again (the same values: the row clock repeats it bit for bit)."""

    RECORD = 3

    def __init__(self, path: Path, fresh: bool):
        """Open ``path`` to append to (``fresh``: emptied first; else a record a
        kill cut is cut off, so that the next one is read whole)."""
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        flags = os.O_WRONLY | os.O_CREAT | os.O_APPEND | (os.O_TRUNC if fresh else 0)
        self._fd = os.open(self.path, flags, 0o644)
        weakref.finalize(self, os.close, self._fd)
        size = os.fstat(self._fd).st_size
        os.ftruncate(self._fd, size - size % (8 * self.RECORD))

    def command(self, number: int, rows_after: int | None, state_after: int) -> None:
        rows = -1 if rows_after is None else rows_after
        os.write(self._fd, np.array([number, rows, state_after], np.float64).tobytes())

    def changes(self, first: int, jumps: np.ndarray) -> None:
        """Changes ``first``, ``first + 1``, ... moved the resting sensation by ``jumps``."""
        jumps = np.asarray(jumps, dtype=float).reshape(-1)
        if not len(jumps):
            return
        records = np.zeros((len(jumps), self.RECORD))
        records[:, 0] = -1.0 - (first + np.arange(len(jumps)))
        records[:, 1] = jumps
        os.write(self._fd, records.tobytes())

    @classmethod
    def read(cls, path: Path) -> tuple[dict, dict, dict] | None:
        """``(rows_after, state_after, jumps)`` of the log at ``path`` (command
        number -> rows / world state; change -> jump; a later record of one
        number wins), rows_after empty on the wall clock; None when missing."""
        try:
            data = np.fromfile(path, dtype=np.float64)
        except (OSError, ValueError):
            return None
        records = data[:len(data) - len(data) % cls.RECORD].reshape(-1, cls.RECORD)
        rows_after, state_after, jumps = {}, {}, {}
        for key, first, second in records:
            if key >= 0:
                if first >= 0:
                    rows_after[int(key)] = int(first)
                state_after[int(key)] = int(second)
            else:
                jumps[int(-1 - key)] = float(first)
        return rows_after, state_after, jumps


def write_clock_truth(path: Path, rows_after: dict, state_after: dict, clocked_body=None,
                      whole: bool = True) -> None:
    """Write the body's record (``clocked_body``: its ``ClockedBody`` on the row
    clock, None on the wall clock; ``whole``: of every command of the run),
    replacing ``path`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {"row_numbers": np.asarray(sorted(rows_after), dtype=np.int64),
              "state_numbers": np.asarray(sorted(state_after), dtype=np.int64),
              "whole": np.bool_(whole)}
    arrays["rows_after"] = np.asarray([rows_after[n] for n in arrays["row_numbers"]], np.int64)
    arrays["state_after"] = np.asarray([state_after[n] for n in arrays["state_numbers"]],
                                       np.int64)
    if clocked_body is not None:
        arrays.update(rows=np.int64(clocked_body.row), held_rows=np.int64(clocked_body.held_rows),
                      rest_jumps=np.asarray(clocked_body.rest_jumps, dtype=float))
    partial = path.with_name(path.name + ".partial")
    with open(partial, "wb") as out:
        np.savez(out, **arrays)
    os.replace(partial, path)


def read_clock_truth(path: Path) -> dict | None:
    """``rows_after`` and ``state_after`` (command number -> rows executed / world
    state), ``whole`` and, on the row clock, ``rows``, ``held_rows``,
    ``rest_jumps``; None when ``path`` is missing."""
    if not Path(path).is_file():
        return None
    with np.load(path) as stored:
        arrays = {key: stored[key] for key in stored.files}
    truth = {"rows_after": dict(zip(arrays["row_numbers"].tolist(), arrays["rows_after"].tolist())),
             "state_after": dict(zip(arrays["state_numbers"].tolist(),
                                     arrays["state_after"].tolist())),
             "whole": bool(arrays["whole"])}
    if "rows" in arrays:
        truth.update(rows=int(arrays["rows"]), held_rows=int(arrays["held_rows"]),
                     rest_jumps=arrays["rest_jumps"])
    return truth
