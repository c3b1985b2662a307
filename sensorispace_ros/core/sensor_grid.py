"""The external grid of sensor positions, as ground truth for the evaluator.

The object moves on a square grid, so every compensated sensor position lies
on a square lattice of the same step. Two numbers read that lattice:

- ``diagonal_ratio``: the paper's exploration makes opposite sides of every
  grid square equal but never compares the two diagonals (paper Fig. 13,
  "inconsistent diagonal lengths" that let the 3-D representation curve).
  The ratio of the internal lengths of the (+1, +1) and (+1, -1) diagonals
  is 1 for a representation as regular as the plane.
- ``missed_in_ring``: the lattice positions in the arm's working ring that no
  point of view covers (paper Fig. 7a's red outline: a position that should
  have been compensated but was not), for any strategy: the lattice is the
  one most positions lie on, wherever the strategy anchored it.

Evaluation only: these take the true positions.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sensorispace_ros.core import arm

# Sensor positions with an unsplit point of view (paper Sec. 3.1): the tip at
# least one segment from the base, at most the arm's length.
WORKING_RING = (float(arm.SEGMENT_LENGTHS[0]), float(sum(arm.SEGMENT_LENGTHS)))
STEP_TOL = 0.01           # a grid neighbour: within 1 % of a step of its lattice offset
COVER_TOL = 0.25          # a position is covered by a POV within a quarter step


def _positions(positions) -> np.ndarray:
    P = np.asarray(positions, dtype=float)
    if P.ndim != 2 or P.shape[1] != 2:
        raise ValueError(f"positions must be a (P, 2) array, got shape {P.shape}")
    if not np.all(np.isfinite(P)):
        raise ValueError("positions contain NaN or infinite values")
    return P


def _spacing(spacing) -> float:
    if not (np.isfinite(spacing) and spacing > 0):
        raise ValueError(f"spacing must be a finite step > 0, got {spacing}")
    return float(spacing)


def offset_pairs(positions, spacing: float, offset) -> np.ndarray:
    """``(K, 2)`` index pairs ``(i, j)`` with ``positions[j]`` at
    ``positions[i] + offset * spacing`` (within ``STEP_TOL`` of a step)."""
    P, s = _positions(positions), _spacing(spacing)
    if len(P) == 0:
        return np.zeros((0, 2), dtype=int)
    distance, index = cKDTree(P).query(P + s * np.asarray(offset, dtype=float), k=1)
    found = np.flatnonzero(distance < STEP_TOL * s)
    return np.stack([found, index[found]], axis=1).astype(int)


def diagonal_ratio(distance, positions, spacing: float) -> float:
    """Mean internal length of the (+1, +1) grid diagonals over that of the
    (+1, -1) ones (``distance``: (P, P) internal metric); NaN without both."""
    D = np.asarray(distance, dtype=float)
    P = _positions(positions)
    if D.shape != (len(P), len(P)):
        raise ValueError(f"distance must be ({len(P)}, {len(P)}) for {len(P)} positions, "
                         f"got {D.shape}")
    rising = offset_pairs(P, spacing, (1, 1))
    falling = offset_pairs(P, spacing, (1, -1))
    if len(rising) == 0 or len(falling) == 0:
        return float("nan")
    return float(np.mean(D[rising[:, 0], rising[:, 1]]) / np.mean(D[falling[:, 0], falling[:, 1]]))


def lattice_origin(positions, spacing: float) -> np.ndarray:
    """A position on the lattice most ``positions`` lie on (the one whose
    offset modulo the step is shared by the most others)."""
    P, s = _positions(positions), _spacing(spacing)
    if len(P) == 0:
        raise ValueError("positions: no position to find a lattice from")
    phase = np.mod((P - P[0]) / s, 1.0)
    phase[phase >= 1.0] = 0.0                       # mod can round up to the period
    tree = cKDTree(phase, boxsize=1.0)
    shared = tree.query_ball_point(phase, r=COVER_TOL, return_length=True)
    return P[int(np.argmax(shared))].copy()


def ring_positions(positions, spacing: float, ring=WORKING_RING) -> np.ndarray:
    """``(M, 2)`` lattice positions (``lattice_origin``'s lattice) with
    ``ring[0] <= |p| <= ring[1]``: the positions the arm can compensate."""
    inner, outer = (float(r) for r in ring)
    if not 0 <= inner < outer:
        raise ValueError(f"ring must be (inner, outer) with 0 <= inner < outer, got {ring}")
    s = _spacing(spacing)
    origin = lattice_origin(positions, s)
    steps = [np.arange(np.ceil((-outer - c) / s), np.floor((outer - c) / s) + 1) for c in origin]
    nodes = origin + s * np.stack(np.meshgrid(*steps, indexing="ij"), axis=-1).reshape(-1, 2)
    radius = np.hypot(nodes[:, 0], nodes[:, 1])
    return nodes[(radius >= inner) & (radius <= outer)]


def missed_in_ring(positions, spacing: float, ring=WORKING_RING) -> np.ndarray:
    """``(M, 2)`` ``ring_positions`` with no position within ``COVER_TOL``
    of a step: compensable but not compensated."""
    P = _positions(positions)
    nodes = ring_positions(P, spacing, ring)
    distance, _ = cKDTree(P).query(nodes, k=1)
    return nodes[distance > COVER_TOL * _spacing(spacing)]
