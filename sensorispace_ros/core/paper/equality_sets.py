"""Equality sets of simulation 2, the paper's analytic shortcut (paper Sec. 5.1,
"Optimized simulation setting").

Every object translation within the explored grid, applied to every known
POV, is compensated by the known POV whose sensor moved by the same
displacement. All POV changes that compensate one object displacement form
one *equality set*: their internal distances must become equal (paper Eq.
common_distance). With the paper's shortcut this reduces to grouping POV
pairs by their lattice displacement.
"""
from __future__ import annotations

import numpy as np


def equality_sets_from_poses(true_positions: np.ndarray, spacing: float, *,
                             lattice_tol: float = 0.25):
    """POV pairs grouped by the object displacement that relates them.

    ``true_positions`` ``(P, 2)``: sensor positions of the POVs (ground
    truth, standing in for the analytic compensation of the paper).
    Displacements are rounded to integer multiples of ``spacing``; ``delta``
    and ``-delta`` are one unordered displacement, so each unordered pair
    ``{i, j}`` (``i != j``) appears once, oriented ``(i, j)`` so that its
    lattice displacement ``(dx, dy)`` has ``dx > 0`` or ``dx == 0, dy > 0``.

    Returns ``pairs`` ``(K, 2)`` and ``set_ids`` ``(K,)`` (0-based, numbered
    in lexicographic order of the displacement).

    The lattice's offset is the circular mean of the positions' phases
    (``position / spacing mod 1`` per axis). A position farther than
    ``lattice_tol * spacing`` from that lattice belongs to no pair: in
    simulation 1 this is the initial POV, whose object position (the grid
    centre) is half a cell off the grid, so no grid displacement reaches it.
    """
    positions = np.asarray(true_positions, dtype=float)
    if positions.ndim != 2 or positions.shape[1] != 2:
        raise ValueError(f"true_positions must have shape (P, 2), got {positions.shape}")
    if not np.all(np.isfinite(positions)):
        raise ValueError("true_positions contains non-finite values")
    if not spacing > 0:
        raise ValueError(f"spacing must be > 0, got {spacing}")
    if not 0 < lattice_tol < 0.5:
        raise ValueError(f"lattice_tol must be in (0, 0.5), got {lattice_tol}")
    if len(positions) < 2:
        return np.empty((0, 2), dtype=int), np.empty(0, dtype=int)

    scaled = positions / spacing
    phase = np.angle(np.mean(np.exp(2j * np.pi * scaled), axis=0)) / (2 * np.pi)
    offset = scaled - phase
    lattice = np.rint(offset)
    on_lattice = np.flatnonzero(np.abs(offset - lattice).max(axis=1) <= lattice_tol)
    lattice = lattice.astype(np.int64)
    i, j = np.triu_indices(len(on_lattice), k=1)
    i, j = on_lattice[i], on_lattice[j]
    if len(i) == 0:
        return np.empty((0, 2), dtype=int), np.empty(0, dtype=int)
    delta = lattice[j] - lattice[i]
    # Orient each pair so its displacement is the canonical one of +-delta.
    flip = (delta[:, 0] < 0) | ((delta[:, 0] == 0) & (delta[:, 1] < 0))
    pairs = np.stack([np.where(flip, j, i), np.where(flip, i, j)], axis=1)
    delta[flip] *= -1
    # One int64 key per displacement, ordered like (dx, dy) lexicographically:
    # np.unique on rows (axis=0) gives the same output but sorts a structured
    # view, much more slowly (docs/benchmarks.md).
    low = delta.min(axis=0)
    width = int(delta[:, 1].max() - low[1]) + 1
    key = (delta[:, 0] - low[0]) * width + (delta[:, 1] - low[1])
    _, set_ids = np.unique(key, return_inverse=True)
    return pairs, set_ids.ravel()


def equality_sets_by_orientation(true_poses: np.ndarray, spacing: float, *,
                                 lattice_tol: float = 0.25, angle_tol: float = 1e-3):
    """``equality_sets_from_poses`` for a turning object: POVs grouped by the
    eye's orientation (one object orientation each, within ``angle_tol``),
    pairs only within an orientation, one set per lattice displacement over
    all orientations (a translation of the object moves the eye by the same
    step whatever the orientation). Turns are left out of the sets, so the
    metric regularisation acts along translations only (the paper's
    Discussion: a turn's compensating step depends on the distance to its
    centre). ``true_poses`` ``(P, 3)``; returns ``pairs``, ``set_ids``."""
    poses = np.asarray(true_poses, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"true_poses must have shape (P, 3), got {poses.shape}")
    turn = np.round(np.angle(np.exp(1j * poses[:, 2])) / angle_tol).astype(np.int64)
    all_pairs, all_delta = [], []
    for value in np.unique(turn):
        members = np.flatnonzero(turn == value)
        pairs, _ = equality_sets_from_poses(poses[members, :2], spacing,
                                            lattice_tol=lattice_tol)
        if len(pairs):
            pairs = members[pairs]
            all_pairs.append(pairs)
            all_delta.append(np.rint((poses[pairs[:, 1], :2] - poses[pairs[:, 0], :2])
                                     / spacing).astype(np.int64))
    if not all_pairs:
        return np.empty((0, 2), dtype=int), np.empty(0, dtype=int)
    _, set_ids = np.unique(np.concatenate(all_delta), axis=0, return_inverse=True)
    return np.concatenate(all_pairs), set_ids.ravel()
