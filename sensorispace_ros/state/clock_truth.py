"""What the body node knew of time in a world on its own clock, written when
the run is over (``<checkpoint_dir>/body.truth.npz``) so that a launched run
is evaluated as an offline one (``evaluation.graph_clock``): the rows executed
after each command (row clock) and the world state each was answered in; on
the row clock also the clock's end, its held rows and how far each change
moved the sensation at the resting arm. Never read by the agent. A body
restarted on the row clock knows only its own commands (``graph.nodes.body_clock``):
its record says it is not ``whole``. Also the layout of ``body.clock`` (a
``RestingStateFile``): the last command's number and where the clock stood
before and after it (``clock_record``, ``split_clock_record``).
Pure numpy, no rclpy."""
from __future__ import annotations

import os
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
