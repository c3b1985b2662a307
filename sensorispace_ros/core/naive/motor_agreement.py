"""POVs few equality sets tie, taken where motor space agrees with their place.

A POV found late in a run is tied to the others by one to three sets. The
lattice places it all the same (its pairs give its step from a POV the
lattice holds), but a place that rests on one pair is not checked by any
other: a wrong pair would put it anywhere (a far alias). Left out of the
implied sets, such a POV floats in the representation, where only its
few found pairs hold it.

Motor space gives a second, independent opinion: the POVs whose loops pass
nearest a POV's loop stand a few lattice steps from it, on any arm (the
body is continuous). How few is measured on the POVs enough sets tie: the
largest median lattice distance (Chebyshev) from one of them to the
``NEIGHBOURS`` POVs nearest it in motor space. A POV tied more loosely is
taken where its own median stays within that. The bound is generous on
purpose: a POV left out floats many steps off in the representation,
farther than one a few steps off its place would sit. A far alias's neighbours
stand where it truly is, many steps from its place; an error of one step
passes, as it would among the POVs enough sets tie.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.naive.points_of_view import torus_tree

NEIGHBOURS = 6          # POVs nearest in motor space whose places are compared
QUERY_SAMPLES = 20      # samples of each loop, evenly spread, that stand for it


def lattice_spread(samples: np.ndarray, ij: np.ndarray, members: np.ndarray,
                   candidates: np.ndarray) -> np.ndarray:
    """``(len(candidates),)``: for each candidate POV, the median Chebyshev
    distance between its lattice place ``ij`` and those of the ``NEIGHBOURS``
    ``members`` (other than itself) whose loops ``samples`` ``(P, N, M)``
    pass nearest its own (NaN where fewer members exist)."""
    members = np.asarray(members, dtype=int)
    candidates = np.asarray(candidates, dtype=int)
    out = np.full(len(candidates), np.nan)
    if len(members) <= NEIGHBOURS or not len(candidates):
        return out
    taken = np.unique(np.linspace(0, samples.shape[1] - 1,
                                  min(QUERY_SAMPLES, samples.shape[1])).astype(int))
    loops = samples[:, taken]
    tree = torus_tree(loops[members].reshape(-1, samples.shape[2]))
    owner = np.repeat(members, len(taken))
    k = min(len(owner), (NEIGHBOURS + 1) * len(taken))
    for row, pov in enumerate(candidates):
        distance, index = tree.query(loops[pov], k=k)
        order = np.argsort(distance.ravel(), kind="stable")
        nearest = _first_distinct(owner[index.ravel()[order]], exclude=pov)
        if len(nearest) == NEIGHBOURS:
            out[row] = np.median(np.abs(ij[nearest] - ij[pov]).max(axis=1))
    return out


def _first_distinct(owners: np.ndarray, exclude: int) -> np.ndarray:
    """The first ``NEIGHBOURS`` distinct values of ``owners`` other than ``exclude``."""
    _, first = np.unique(owners, return_index=True)
    ordered = owners[np.sort(first)]
    return ordered[ordered != exclude][:NEIGHBOURS]


def agreeing(samples: np.ndarray, ij: np.ndarray, tied: np.ndarray,
             loose: np.ndarray) -> np.ndarray:
    """``(P,)`` bool: the ``loose`` POVs (placed, tied by too few sets) whose
    lattice spread (``lattice_spread``) stays within the largest of the
    ``tied`` POVs' (module docstring)."""
    agree = np.zeros(len(tied), dtype=bool)
    members = np.flatnonzero(tied)
    candidates = np.flatnonzero(loose & ~tied)
    if not len(candidates):
        return agree
    spread = lattice_spread(samples, ij, members, np.concatenate([members, candidates]))
    own, loose_spread = spread[:len(members)], spread[len(members):]
    if not np.isfinite(own).any():
        return agree
    agree[candidates] = loose_spread <= np.nanmax(own)
    return agree
