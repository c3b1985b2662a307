"""A compensation under noise held to its target's matched neighbours.

One displacement of the object moves every pose alike, so POVs that were
neighbours before it are neighbours after it: a row of a snapshot (or its
anchor) that no known POV matches lies, in motor space, near the rows that
were matched, and its compensation must lie near those rows' partners now.
A far pose that senses the target alike (noise hides the difference) does
not. Distances are from a motor state to the nearest sample of a POV, on
the torus of phases (``curve_distances``): the agent's own motor values and
the POVs it walked, nothing of the world.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensorispace_ros.core.motor_loops import loop_chords, wrap_phase


@dataclass
class Neighbours:
    """A frontier row's (or an anchor's) matched neighbours: ``before``
    ``(k,)`` the snapshot's rows nearest its POV (motor space, point to POV curve),
    ``after`` ``(k,)`` the known POVs matched to them now, ``reach`` ``(k,)``
    the distances of the row's POV to the ``before`` POVs' curves."""

    before: np.ndarray
    after: np.ndarray
    reach: np.ndarray


# Matched neighbours a compensation is held to (``held_by_neighbours``).
_NEIGHBOURS = 5


def curve_distances(point: np.ndarray, curves: np.ndarray) -> np.ndarray:
    """Distance (torus of phases) from ``point`` ``(M,)`` to the nearest
    sample of each of ``curves`` ``(K, N, M)``: ``(K,)``."""
    wrapped = wrap_phase(curves - point)
    return np.sqrt(np.min(np.sum(wrapped * wrapped, axis=2), axis=1))


def matched_neighbours(pov_samples, before, after, motor_state) -> Neighbours:
    """The ``_NEIGHBOURS`` matched rows ``before`` whose POVs lie nearest
    ``motor_state`` (a POV's first sample), with their partners ``after``."""
    reach = curve_distances(motor_state, pov_samples[before])
    nearest = np.argsort(reach, kind="stable")[:_NEIGHBOURS]
    return Neighbours(before[nearest], after[nearest], reach[nearest])


def held_by_neighbours(pov_samples, neighbours: Neighbours, motor_state, *, ratio: float,
                       slack: float) -> bool:
    """Whether ``motor_state`` (a frontier row's compensation) lies as near
    its row's matched neighbours' partners as the row lay to the
    neighbours: the object moved every pose by one displacement, so
    neighbours stay neighbours. Within ``ratio`` times the row's distance
    plus ``slack`` (the arm's joints map a pose difference to motor
    distances that differ from place to place) for most of the neighbours
    (a wrong match among them is outvoted), and for every one no nearer
    than that distance over ``ratio + 1`` (on a partner's pose it is that
    neighbour's compensation, not the row's)."""
    near = curve_distances(motor_state, pov_samples[neighbours.after])
    agree = near <= ratio * neighbours.reach + slack
    apart = near >= neighbours.reach / (ratio + 1)
    return 2 * int(np.sum(agree)) > len(agree) and bool(np.all(apart))


def loop_distances(point: np.ndarray, loops: np.ndarray) -> np.ndarray:
    """Distance (torus of phases) from ``point`` ``(M,)`` to each closed
    polyline through the samples of ``loops`` ``(K, N, M)``: ``(K,)``. A
    POV's samples lie a walk's step apart; between them the loop runs
    along the chord, so a pose on the loop lies near it, not only near a
    sample."""
    start = wrap_phase(loops - point)
    chord = loop_chords(loops)
    length2 = np.sum(chord * chord, axis=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        along = np.clip(np.where(length2 > 0, -np.sum(start * chord, axis=2) / length2, 0.0),
                        0.0, 1.0)
    nearest = start + along[..., None] * chord
    return np.sqrt(np.min(np.sum(nearest * nearest, axis=2), axis=1))
