"""Helpers shared by the bag tests (imported by name: pytest puts this folder on sys.path)."""
from __future__ import annotations

import time


def wait_for(condition, timeout_s: float, what: str, spin=None) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        if spin is not None:
            spin()
        else:
            time.sleep(0.05)


PARAMS_FILE = """/**:
  ros__parameters:
    seed: 7
    world:
      grid_count: 5
    arm:
      initial_motor_state: [0.1, -1.5, 2.2, -3.0]
"""
