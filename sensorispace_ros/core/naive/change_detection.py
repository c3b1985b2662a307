"""How the naive agent tells, from its sensory flow alone, that its world
changed.

No one tells the agent when the environment changes. It knows motor states
whose sensation it has just sensed (its resting state, its anchor); sensed
again, such a state gives what it gave, up to the noise the agent measured
(``noise.measure_body``: a per-receptor standard deviation). A receptor
farther than ``Z_BAND`` standard deviations of a difference of two
sensings (sqrt 2 sd) from the remembered value is a change; float64
round-off bounds the band from below, so a noiseless body flags any change
of the bits that is more than round-off. A non-finite output (a lost frame)
is no evidence either way. A flag is confirmed by sensing the state once
more: a single wild output is not a change.
"""
from __future__ import annotations

import numpy as np

Z_BAND = 6.0
ROUND_OFF = 64 * np.finfo(float).eps


def tolerance(noise_sd: float, reference: np.ndarray) -> np.ndarray:
    """Per-receptor half-width of the band around ``reference``."""
    reference = np.asarray(reference, dtype=float)
    scale = np.where(np.isfinite(reference), np.abs(reference), 0.0)
    return np.maximum(Z_BAND * np.sqrt(2.0) * float(noise_sd), ROUND_OFF * np.maximum(scale, 1.0))


def band(noise_sd: float, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(low, high)``: what sensing the reference's state again may give
    without a change (a non-finite reference receptor accepts anything)."""
    reference = np.asarray(reference, dtype=float)
    half = tolerance(noise_sd, reference)
    finite = np.isfinite(reference)
    low = np.where(finite, reference - half, -np.inf)
    high = np.where(finite, reference + half, np.inf)
    return low, high


def differs(noise_sd: float, reference: np.ndarray, sensed: np.ndarray) -> bool:
    """Does ``sensed`` (the reference's motor state sensed again) lie outside
    the band? Receptors non-finite in either are left out."""
    reference = np.asarray(reference, dtype=float)
    sensed = np.asarray(sensed, dtype=float)
    both = np.isfinite(reference) & np.isfinite(sensed)
    half = tolerance(noise_sd, reference)
    return bool(np.any(np.abs(sensed - reference)[both] > half[both]))


class ChangeLog:
    """Every test the agent made: the row its reference was sensed at, the
    row of the test, whether it flagged a change, the motor state tested
    (body units) and what kind of test (``hold``: idle watching; ``cut``: a
    check after a reaction). Rows are the clock's (ground truth joins them)."""

    def __init__(self):
        self.reference_row: list[int] = []
        self.test_row: list[int] = []
        self.flagged: list[bool] = []
        self.motor_state: list[np.ndarray] = []
        self.kind: list[str] = []

    def add(self, reference_row: int, test_row: int, flagged: bool, motor_state, kind: str):
        self.reference_row.append(int(reference_row))
        self.test_row.append(int(test_row))
        self.flagged.append(bool(flagged))
        self.motor_state.append(np.asarray(motor_state, dtype=float).copy())
        self.kind.append(kind)
