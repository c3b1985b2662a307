"""Geometry of closed paths in the motor torus, shared by the analytic and the
sensory point-of-view samplers. Knows nothing of the arm, so the naive
modules can use it without loading the forward model.
"""
from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi


def wrap_phase(angle) -> np.ndarray:
    """``angle`` (phases) wrapped into ``[-pi, pi)``: a difference on the
    torus of phases taken the short way round."""
    return (angle + np.pi) % TWO_PI - np.pi


def loop_chords(samples: np.ndarray) -> np.ndarray:
    """``(..., N, J)``: the chord from each sample of closed loops
    ``(..., N, J)`` to the next round the loop (the last back to the first),
    on the torus of phases."""
    return wrap_phase(np.roll(samples, -1, axis=-2) - samples)


def loop_winding(path: np.ndarray) -> np.ndarray:
    """Per-joint number of 2 pi turns between the start and the end of a
    closed loop, ``(J,)`` int.

    ``path`` is an unwrapped motor path ``(n, J)`` whose end returns to its
    start modulo 2 pi per joint. A POV whose tip lies at ``|tip| < 1`` is split
    into two loops and the traced one winds around a joint circle (nonzero
    entry, paper Fig. 5b); a whole POV comes back with zero winding in every
    joint.
    """
    path = np.asarray(path, dtype=float)
    if path.ndim != 2 or len(path) < 2:
        raise ValueError(f"path must have shape (n >= 2, joints), got {path.shape}")
    return np.rint((path[-1] - path[0]) / TWO_PI).astype(int)


def closure_gap_ratio(path: np.ndarray) -> float:
    """How far an unwrapped motor path ``(n, J)`` that was walked round a
    loop ends from its start, relative to the path's own length:
    ``|path[-1] - path[0]| / sum of its chords``.

    A walk that closed in the motor space ends about one step from its
    start (a small ratio). One whose ends met only in the torus, a period
    apart in some coordinates, ends a whole period away: its ratio is of
    the order of one (a period over a loop at least a period long). The
    rule names no joint: it is the distance between two points.
    """
    path = np.asarray(path, dtype=float)
    if path.ndim != 2 or len(path) < 2:
        raise ValueError(f"path must have shape (n >= 2, joints), got {path.shape}")
    length = float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))
    gap = float(np.linalg.norm(path[-1] - path[0]))
    return gap / length if length > 0 else np.inf


def doubles_back(samples: np.ndarray) -> np.ndarray:
    """``(P,)`` bool: which closed loops ``(P, N, J)`` of samples (in order
    round the loop, phases) turn back on themselves somewhere: two
    consecutive chords (the last back to the first sample included) more
    than a right angle apart.

    Samples spread evenly round a smooth loop turn by a few degrees from
    chord to chord. A walk whose front turned round walked part of its
    loop twice, out and back: its samples double back at both ends of
    that stretch, and the loop is not its POV's whole level set.
    """
    samples = np.asarray(samples, dtype=float)
    if samples.ndim != 3 or samples.shape[1] < 3:
        raise ValueError(f"samples must have shape (P, N >= 3, joints), got {samples.shape}")
    chords = loop_chords(samples)
    turn = np.sum(chords * np.roll(chords, -1, axis=1), axis=2)
    return np.any(turn < 0.0, axis=1)
