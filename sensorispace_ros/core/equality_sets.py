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
    in lexicographic order of the displacement). Raises if a position is
    farther than ``lattice_tol * spacing`` from the lattice through the
    first one (the shortcut assumes grid displacements).
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

    offset = (positions - positions[0]) / spacing
    lattice = np.rint(offset)
    off_lattice = np.abs(offset - lattice).max()
    if off_lattice > lattice_tol:
        raise ValueError(f"true_positions are {off_lattice:.3f} spacings off the lattice "
                         f"of spacing {spacing} (lattice_tol={lattice_tol})")
    lattice = lattice.astype(np.int64)
    i, j = np.triu_indices(len(positions), k=1)
    delta = lattice[j] - lattice[i]
    # Orient each pair so its displacement is the canonical one of +-delta.
    flip = (delta[:, 0] < 0) | ((delta[:, 0] == 0) & (delta[:, 1] < 0))
    pairs = np.stack([np.where(flip, j, i), np.where(flip, i, j)], axis=1)
    delta[flip] *= -1
    _, set_ids = np.unique(delta, axis=0, return_inverse=True)
    return pairs, set_ids.ravel()
