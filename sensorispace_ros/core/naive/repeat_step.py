"""Whether one motor state's repeats, sensed in a row, saw two worlds; the
robust spread (``robust_sd``) the agent measures its noise with.

The agent measures its noise by sensing its start state again and again in
one call (``noise.measure_noise``). On a world with a clock of its own the
world may change between two of those rows; the repeats then hold two
clusters one after the other, and their spread is the change, not the noise
(a change halfway through makes the estimate the size of the change, and
the agent then tests everything against it).

The rows are in the order they were sensed, so a change is a step: for some
split ``k`` the medians before and after it differ, in some receptor, by
more than ``z`` standard errors of the difference of two medians, the noise
taken from each part's own spread around its median (the step does not
inflate it), and the whole's robust spread is at least ``_EXPLAINS`` times
the parts' (the step, not the noise, spreads the repeats). ``z`` holds the
splits and receptors tested to ``_FALSE_STEP`` false steps a call of
independent noise (Bonferroni); with the second condition a false step is
rarer still, and costs little: the estimate from the last part's repeats.
Parts of fewer than ``_MIN_PART`` rows are not tested: such a step barely
moves a robust spread. Where the outputs lie on a lattice, a step must
exceed its step.
"""
from __future__ import annotations

import numpy as np
from scipy.stats import norm

_MIN_PART = 4
_FALSE_STEP = 1e-3
# A step is taken only where it explains the repeats' spread: the whole's
# robust spread at least this many times the parts' own.
_EXPLAINS = 2.0
# MAD -> standard deviation of a normal distribution.
_MAD_TO_SD = 1.482602218505602


def robust_sd(deviations: np.ndarray) -> float:
    """``1.4826 * median |deviation|`` of the finite entries (0 if none)."""
    values = np.abs(np.asarray(deviations, dtype=float))
    values = values[np.isfinite(values)]
    return float(_MAD_TO_SD * np.median(values)) if len(values) else 0.0


def last_world_start(repeats: np.ndarray, quantum: float = 0.0) -> int:
    """The first row of the last world the time-ordered ``repeats`` ``(R, S)``
    of one motor state saw: the split that leaves the least absolute
    deviation from the two parts' medians, if its step stands out; else 0.
    Rows with a lost value count for neither part."""
    repeats = np.asarray(repeats, dtype=float)
    finite = np.flatnonzero(np.all(np.isfinite(repeats), axis=1))
    rows = repeats[finite]
    n_rows, n_sensors = rows.shape
    splits = np.arange(_MIN_PART, n_rows - _MIN_PART + 1)
    if not len(splits):
        return 0
    medians = [(np.median(rows[:k], axis=0), np.median(rows[k:], axis=0)) for k in splits]
    deviations = [np.concatenate([rows[:k] - before, rows[k:] - after])
                  for k, (before, after) in zip(splits, medians)]
    best = int(np.argmin([np.sum(np.abs(d)) for d in deviations]))
    k = int(splits[best])
    spread = robust_sd(deviations[best])
    if robust_sd(rows - np.median(rows, axis=0)) <= _EXPLAINS * spread:
        return 0
    z = norm.isf(_FALSE_STEP / (2.0 * len(splits) * n_sensors))
    error = max(spread * np.sqrt(0.5 * np.pi * (1.0 / k + 1.0 / (n_rows - k))), quantum)
    gap = np.max(np.abs(medians[best][1] - medians[best][0]))
    return int(finite[k]) if gap > z * error else 0
