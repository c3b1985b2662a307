"""What two sensings of one relative pose differ by beyond the receptor noise.

A sweep row matches a snapshot's row when the POV swept now sits, relative
to the object, where the snapshot's POV sat then. Each of the two POVs was
placed by compensations whose pose errors the noise left (and chains of
anchors added up); a pose error that a world's weak sensory direction hid
when the POV was found shows in another world's sensation. So true matches
differ by more than the noise of their two sensings, and a test against the
noise alone refuses most of them.

The agent measures that excess from its own sweeps: the pairs of rows that
are each other's nearest neighbour and lie ``_CLEAR`` times nearer each
other than to any other row on either side are matches whatever their
scale. The discrepancy is the per-receptor variance that, added to the two
sensings' noise, puts the median of those pairs' chi-square statistics at
the median of chi-square with one degree per receptor (0 where they show no
excess, or where fewer than ``_MIN_PAIRS`` pairs stand that clear). The
median keeps the estimate off the tail of poorly placed POVs, which stay
unmatched rather than widen every test.

The agent adds it to its sweep matches' tests where ``naive.match_discrepancy``
is set (``sweep_discrepancy``): more rows match and more
equality pairs join the sets, and the frontier searches it locates find far
aliases more often (docs/noise.md, "Matches that differ by more than the
noise").
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq
from scipy.spatial import cKDTree
from scipy.stats import chi2

from sensorispace_ros.core.naive.equality_sets import finite_rows

# A pair is clear of every other row when it lies this many times nearer.
_CLEAR = 0.1
# Clear pairs below which the excess is not measured.
_MIN_PAIRS = 8


def clear_pairs(reference: np.ndarray, current: np.ndarray, tree: cKDTree | None = None):
    """Rows ``(i, j)`` of ``reference`` and ``current`` that are each
    other's nearest neighbour, ``_CLEAR`` times nearer each other than to
    the next row on either side; finite rows only. ``tree``: a ``cKDTree``
    of ``finite_rows(current, -1)`` (``equality_sets``) to reuse across calls."""
    empty = np.zeros(0, dtype=int)
    ref_rows = np.flatnonzero(np.all(np.isfinite(reference), axis=1))
    if len(ref_rows) < 2 or np.sum(np.all(np.isfinite(current), axis=1)) < 2:
        return empty, empty
    ref = reference[ref_rows]
    # Lost rows of ``current`` lie at -LOST_ROW: never among a finite row's two nearest.
    tree = cKDTree(finite_rows(current, -1.0)) if tree is None else tree
    forward, nearest = tree.query(ref, k=2)
    backward, back = cKDTree(ref).query(current[nearest[:, 0]], k=2)
    clear = (back[:, 0] == np.arange(len(ref))) & \
        (forward[:, 0] < _CLEAR * forward[:, 1]) & (forward[:, 0] < _CLEAR * backward[:, 1])
    return ref_rows[clear], nearest[clear, 0]


def match_discrepancy(differences: np.ndarray, noise_var: np.ndarray) -> float:
    """The per-receptor variance ``tau2`` beyond the noise: ``differences``
    ``(K, S)`` between the rows of clear pairs, ``noise_var`` ``(K,)`` the
    per-receptor noise variance of each difference. ``tau2`` solves
    ``median(|d|^2 / (noise_var + tau2)) = median of chi-square(S)``."""
    differences = np.asarray(differences, dtype=float)
    if len(differences) < _MIN_PAIRS:
        return 0.0
    squared = np.sum(differences ** 2, axis=1)
    noise_var = np.asarray(noise_var, dtype=float)
    target = chi2.median(differences.shape[1])

    def excess(tau2: float) -> float:
        return float(np.median(squared / (noise_var + tau2))) - target

    if excess(0.0) <= 0.0:
        return 0.0
    return float(brentq(excess, 0.0, float(np.max(squared)) / target, xtol=1e-30,
                        rtol=1e-6))


def sweep_discrepancy(snapshots, current: np.ndarray, noise_sd: float,
                      tree: cKDTree | None = None) -> float:
    """``match_discrepancy`` of the clear pairs of every snapshot's rows
    (``sensations``; ``counts`` the sensings averaged in each, None: one)
    with the sweep ``current`` (one sensing a row; ``tree`` as ``clear_pairs``
    takes it), ``noise_sd`` the noise of one sensing per receptor."""
    differences, variances = [], []
    tree = cKDTree(finite_rows(current, -1.0)) if tree is None and len(current) else tree
    for snap in snapshots:
        before, after = clear_pairs(snap.sensations, current, tree)
        counts = np.ones(len(before)) if snap.counts is None else snap.counts[before]
        differences.append(snap.sensations[before] - current[after])
        variances.append(noise_sd ** 2 * (1.0 / counts + 1.0))
    if not differences:
        return 0.0
    return match_discrepancy(np.concatenate(differences), np.concatenate(variances))
