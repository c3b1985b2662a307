"""The lattice of equality sets that hold a few wrong pairs, and the sets it
implies.

Under noise a few matches pair two POVs that the displacement does not
relate: one such pair leaves no exact null space, so ``lattice`` finds no
lattice. Where it finds none, ``trimmed_lattice`` embeds the POVs by
smallest eigenvectors of the constraints all the same (``EMBEDDINGS``: those
before the eigenvalues' largest jump, else the two smallest, else the two
that move the most POVs), reads every pair's step in the reduced basis
against its set's median step, drops the pairs farthest from a whole step,
and embeds again, until every pair agrees; the pairs kept must then pass
``lattice_coordinates``'s exact test with a plane's lattice, one POV to a
point but for a few (``_a_plane``). Where no embedding gives one, it tries
again without the POVs fewer than two sets tie (``tied_twice``), which can
slide. ``lattice_equalities`` tries last without the POVs a null direction of
the constraints moves nearly alone (``sliding_povs``): two POVs tied to the
others along one step only slide together, and their direction leaves the
null space three-dimensional however well the other sets agree.

Any two POVs the lattice places are related by the lattice step between
them: ``implied_sets`` gives one set per step, the pairs of POVs that
enough sets tie (a POV whose place rests on one or two pairs may rest
on a wrong one), and those fewer tie where motor space agrees with their
place (``motor_agreement``). ``ImpliedSets``, a mixin of the agents, hands the
representation the found sets less the pairs the trimming dropped, then
these (in the graph the agent publishes them at the end of its run and
withdraws the dropped pairs it had published, so both regularise with the
same sets).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensorispace_ros.core.naive.lattice import (NULL_TOL, Lattice, basis_coordinates,
                                                 lattice_coordinates, smallest_eigenvectors)
from sensorispace_ros.core.naive.motor_agreement import agreeing

__all__ = ["ImpliedSets", "LatticeSets", "implied_sets", "lattice_equalities", "pair_support",
           "set_medians", "sliding_povs", "tied_twice", "trimmed_lattice", "with_vouched"]

MAX_ROUNDS = 24         # embeddings before the pairs must agree
HALF_STEP = 0.5         # a pair farther than this from its set's step (lattice units) is dropped
MAX_DROPPED = 0.05      # a trimming may drop at most this share of the pairs
MAX_SHARED = 0.05       # at most this share of the placed POVs may share a lattice point
SLIDE = 0.25            # a POV carrying this share of a null direction alone slides
SLIDE_GROUP = 32        # ... measured only in a group of at least this many POVs
SLIDE_ROUNDS = 4        # sliding POVs dropped again at most this many times


def set_medians(values: np.ndarray, set_ids: np.ndarray) -> np.ndarray:
    """``(K, d)``: each row's set's median of ``values`` ``(K, d)``, per column."""
    values = np.asarray(values, dtype=float)
    out = np.empty_like(values)
    for col in range(values.shape[1]):
        order = np.lexsort((values[:, col], set_ids))
        ids = set_ids[order]
        starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
        sizes = np.diff(np.r_[starts, len(ids)])
        low = values[order[starts + (sizes - 1) // 2], col]
        high = values[order[starts + sizes // 2], col]
        out[order, col] = np.repeat(0.5 * (low + high), sizes)
    return out


def _embedding(pairs, set_ids, n_povs: int, choose, max_dim: int):
    """``(P, d)`` lattice units of the largest tied group (NaN elsewhere) from
    the smallest non-constant eigenvectors ``choose(values, vectors)`` picks
    (column indices); None when there is too little to embed."""
    smallest = smallest_eigenvectors(pairs, set_ids, n_povs, max_dim)
    if smallest is None:
        return None
    group, values, vectors, scale = smallest
    columns = choose(np.maximum(values[1:], 1e-300 * scale), vectors[:, 1:]) + 1
    coords = vectors[:, columns] - vectors[:, columns].mean(axis=0)
    # An embedding flat along a measured direction has no lattice there.
    units = basis_coordinates(coords, flat=1e-12)
    if units is None:
        return None
    placed = np.full((n_povs, len(columns)), np.nan)
    placed[group] = units
    return placed


def _largest_jump(values, vectors) -> np.ndarray:
    """The eigenvectors before the eigenvalues' largest jump."""
    return np.arange(1 + int(np.argmax(values[1:] / values[:-1])))


def _smallest_two(values, vectors) -> np.ndarray:
    return np.arange(2)


def _spread_two(values, vectors) -> np.ndarray:
    """The two eigenvectors that move the most POVs (participation ratio): a
    displacement moves every POV, while a group the others hold by a few
    pairs has a small eigenvalue of its own, on its members alone."""
    magnitude = np.abs(vectors)
    participation = magnitude.sum(axis=0) ** 2 / np.maximum((magnitude ** 2).sum(axis=0), 1e-300)
    return np.sort(np.argsort(-participation, kind="stable")[:2])


# The embeddings a trimming tries, in turn, until one leaves a plane's lattice.
EMBEDDINGS = (_largest_jump, _smallest_two, _spread_two)


def tied_twice(pairs, set_ids, n_povs: int) -> np.ndarray:
    """``(K,)`` bool: the pairs left once every POV in fewer than two distinct
    sets, and every set of one pair, has been left out, again until none is.
    A set of one pair constrains nothing, and a POV one set ties moves with
    that set's step: a chain of them can slide, a direction no displacement
    spans."""
    kept = np.ones(len(pairs), dtype=bool)
    while kept.any():
        alone = np.bincount(set_ids[kept], minlength=int(set_ids.max()) + 1)[set_ids] < 2
        loose = pair_support(pairs[kept & ~alone], set_ids[kept & ~alone], n_povs) < 2
        drop = kept & (alone | loose[pairs[:, 0]] | loose[pairs[:, 1]])
        if not drop.any():
            break
        kept &= ~drop
    return kept


def trimmed_lattice(pairs, set_ids, n_povs: int, max_dim: int = 3):
    """``(Lattice, kept)``: the lattice of the pairs ``kept`` ``(K,)`` bool after
    the pairs that disagree with it were dropped (module docstring), or
    ``(None, kept)`` where no lattice holds. Only a plane's lattice counts:
    one wrong pair left, or a chain of POVs that can slide, leaves one
    direction null, whose line is a lattice too."""
    lattice, kept, _ = _trimmed_from_start(pairs, set_ids, n_povs, max_dim)
    return lattice, kept


def _trimmed_from_start(pairs, set_ids, n_povs: int, max_dim: int):
    """``trimmed_lattice`` and the pairs its trimming started from: every
    pair, or those ``tied_twice`` keeps; ``start & ~kept`` are the pairs
    that disagree with the lattice."""
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    set_ids = np.asarray(set_ids, dtype=int).reshape(-1)
    tied = tied_twice(pairs, set_ids, n_povs)
    # Without POVs that can slide, again only where there were some.
    starts = (np.ones(len(pairs), dtype=bool),) + (() if tied.all() else (tied,))
    for start in starts:
        exact = lattice_coordinates(pairs[start], set_ids[start], n_povs)
        if _a_plane(exact):
            return exact, start, start
        for choose in EMBEDDINGS:
            kept = _trimmed_by(pairs, set_ids, n_povs, start.copy(), choose, max_dim)
            if np.count_nonzero(start & ~kept) > MAX_DROPPED * len(pairs):
                continue
            lattice = lattice_coordinates(pairs[kept], set_ids[kept], n_povs)
            if _a_plane(lattice):
                return lattice, kept, start
    return None, tied, tied


def sliding_povs(pairs, set_ids, n_povs: int) -> np.ndarray:
    """The POVs that a null direction of the constraints moves nearly alone:
    their leverage in the null space less the constant (the squared norm of
    their row in its orthonormal basis) above ``SLIDE``. A plane's lattice
    spreads its two directions over every POV of its group (a leverage of a
    few over the group's size each); a POV whose pairs tie it to the others
    along one step adds a direction of its own, which it carries alone."""
    smallest = smallest_eigenvectors(pairs, set_ids, n_povs, max_dim=8)
    if smallest is None or len(smallest[0]) < SLIDE_GROUP:
        return np.zeros(0, dtype=int)
    group, values, vectors, scale = smallest
    null = vectors[:, np.abs(values) < NULL_TOL * scale]
    basis, singular, _ = np.linalg.svd(null - null.mean(axis=0), full_matrices=False)
    basis = basis[:, singular > 1e-8 * singular.max()] if len(singular) else basis
    return group[np.sum(basis ** 2, axis=1) > SLIDE]


def _without_sliding(pairs, set_ids, n_povs: int) -> np.ndarray:
    """``(K,)`` bool: the pairs that touch no POV ``sliding_povs`` finds,
    found again after each drop (``SLIDE_ROUNDS`` at most)."""
    free = np.ones(len(pairs), dtype=bool)
    for _ in range(SLIDE_ROUNDS):
        sliding = sliding_povs(pairs[free], set_ids[free], n_povs)
        if not len(sliding):
            break
        free &= ~np.isin(pairs, sliding).any(axis=1)
    return free


def _a_plane(lattice: Lattice | None) -> bool:
    """Whether ``lattice`` is a plane's: two dimensions, and one-to-one but
    for a few POVs walked twice (``MAX_SHARED``). Pairs that fold the plane
    onto a strip (a wrong pair left between far POVs) still pass the exact
    test, with whole rows of POVs on one point."""
    if lattice is None or lattice.dim != 2:
        return False
    placed = lattice.ij[lattice.placed]
    shared = len(placed) - len(np.unique(placed, axis=0))
    return shared <= MAX_SHARED * len(placed)


def _trimmed_by(pairs, set_ids, n_povs: int, kept, choose, max_dim: int):
    """``kept`` less the pairs farthest from a whole step of their set's median
    in the embedding ``choose`` picks, embedded again until every pair agrees
    (or ``MAX_ROUNDS``)."""
    for _ in range(MAX_ROUNDS):
        units = _embedding(pairs[kept], set_ids[kept], n_povs, choose, max_dim)
        if units is None:
            return kept
        steps = units[pairs[:, 1]] - units[pairs[:, 0]]
        live = kept & np.all(np.isfinite(steps), axis=1)
        gap = np.full(len(pairs), 0.0)
        gap[live] = np.linalg.norm(
            steps[live] - np.round(set_medians(steps[live], set_ids[live])), axis=1)
        worst = gap.max()
        if worst <= HALF_STEP:
            return kept
        kept &= gap < max(HALF_STEP, 0.5 * worst)
    return kept


def pair_support(pairs, set_ids, n_povs: int) -> np.ndarray:
    """``(P,)``: the number of distinct sets each POV has a pair in."""
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    set_ids = np.asarray(set_ids, dtype=int).reshape(-1)
    members = np.unique(np.stack([np.r_[pairs[:, 0], pairs[:, 1]],
                                  np.r_[set_ids, set_ids]], axis=1), axis=0)
    return np.bincount(members[:, 0], minlength=n_povs)


def implied_sets(lattice: Lattice, usable: np.ndarray):
    """``(pairs (K, 2), set_ids (K,))``: every two ``usable`` POVs the lattice
    places, one set per lattice step between them (steps two pairs or more
    share), the step's sets numbered from 0."""
    index = np.flatnonzero(lattice.placed & usable)
    first, second = np.triu_indices(len(index), 1)
    first, second = index[first], index[second]
    _, set_ids = np.unique(lattice.ij[second] - lattice.ij[first], axis=0, return_inverse=True)
    set_ids = set_ids.reshape(-1)
    shared = np.bincount(set_ids)[set_ids] >= 2
    _, set_ids = np.unique(set_ids[shared], return_inverse=True)
    return np.stack([first, second], axis=1)[shared], set_ids.reshape(-1)


@dataclass
class LatticeSets:
    """What ``lattice_equalities`` found: the sets ``pairs`` / ``set_ids`` the
    lattice implies, the POVs it ``placed`` and took (``usable``), which
    found pairs the trimming ``kept`` (None without found pairs), and which
    it ``withdrawn`` as disagreeing with the lattice (None without a lattice)."""

    pairs: np.ndarray
    set_ids: np.ndarray
    placed: int = 0
    usable: int = 0
    kept: np.ndarray | None = None
    withdrawn: np.ndarray | None = None

    @classmethod
    def none(cls, kept=None) -> "LatticeSets":
        """No implied set (no lattice, or none asked for)."""
        return cls(np.zeros((0, 2), dtype=int), np.zeros(0, dtype=int), kept=kept)


def lattice_equalities(pairs, set_ids, n_povs: int, support: int,
                       vouched=None, samples=None) -> LatticeSets:
    """The sets the lattice of ``pairs`` / ``set_ids`` implies among the POVs
    with a kept pair in ``support`` distinct sets or more (none where no
    lattice holds). ``samples``: the POVs' loops ``(P, N, M)``; with them a
    POV fewer sets tie is taken where motor space agrees with its place
    (``motor_agreement.agreeing``). ``vouched``: ``(ij, placed)``, where a
    search toward an empty lattice point found a POV (``HoleMap``): those
    POVs are taken whatever their support (``with_vouched``)."""
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    set_ids = np.asarray(set_ids, dtype=int).reshape(-1)
    if not len(pairs):
        return LatticeSets.none()
    lattice, kept, start = _trimmed_from_start(pairs, set_ids, n_povs, max_dim=3)
    if lattice is None:
        lattice, kept, start = _trimmed_without_sliding(pairs, set_ids, n_povs, kept)
    if lattice is None:
        return LatticeSets.none(kept)
    tied = pair_support(pairs[kept], set_ids[kept], n_povs)
    usable = tied >= support
    if samples is not None:
        usable |= agreeing(samples, lattice.ij, usable & lattice.placed,
                           lattice.placed & (tied > 0))
    if vouched is not None:
        lattice, usable = with_vouched(lattice, usable, *vouched)
    implied, implied_ids = implied_sets(lattice, usable)
    return LatticeSets(implied, implied_ids, placed=int(np.count_nonzero(lattice.placed)),
                       usable=int(np.count_nonzero(usable & lattice.placed)), kept=kept,
                       withdrawn=start & ~kept)


def _trimmed_without_sliding(pairs, set_ids, n_povs: int, kept):
    """``_trimmed_from_start`` of the pairs ``_without_sliding`` keeps, its
    masks over every pair (a sliding POV's pairs neither kept nor withdrawn);
    ``(None, kept, kept)`` where that gives no lattice either."""
    free = _without_sliding(pairs, set_ids, n_povs)
    if free.all():
        return None, kept, kept
    lattice, kept_free, start_free = _trimmed_from_start(pairs[free], set_ids[free], n_povs,
                                                         max_dim=3)
    if lattice is None:
        return None, kept, kept
    kept, start = np.zeros(len(pairs), dtype=bool), np.zeros(len(pairs), dtype=bool)
    kept[free], start[free] = kept_free, start_free
    return lattice, kept, start


def with_vouched(lattice: Lattice, usable: np.ndarray, ij: np.ndarray, placed: np.ndarray):
    """``(lattice, usable)`` with the POVs another placement ``ij`` / ``placed``
    puts on the lattice: mapped by the integer affine map between the two
    (fitted on the POVs both place and ``usable``, every one of them agreeing),
    those it places where the lattice does, or that the lattice does not
    place, are usable. Unchanged where no such map holds."""
    n = min(len(placed), len(lattice.placed))
    ij, placed = np.asarray(ij[:n], dtype=int), np.asarray(placed[:n], dtype=bool)
    both = np.flatnonzero(lattice.placed[:n] & placed & usable[:n])
    if ij.shape[1] != lattice.dim or len(both) <= 2 * (lattice.dim + 1):
        return lattice, usable
    design = np.c_[ij, np.ones(n, dtype=int)]
    coef = np.round(np.linalg.lstsq(design[both].astype(float), lattice.ij[both].astype(float),
                                    rcond=None)[0]).astype(int)
    mapped = design @ coef
    if np.any(mapped[both] != lattice.ij[both]):
        return lattice, usable
    alone = placed & ~lattice.placed[:n]
    agree = placed & (alone | np.all(mapped == lattice.ij[:n], axis=1))
    grown = Lattice(ij=lattice.ij.copy(), placed=lattice.placed.copy(), residual=lattice.residual)
    grown.ij[:n][alone], grown.placed[:n][alone] = mapped[alone], True
    usable = usable.copy()
    usable[:n] |= agree
    return grown, usable


class ImpliedSets:
    """``equality_sets``: the found sets, then the lattice's (module docstring)."""

    def equality_sets(self):
        """``(pairs (K, 2), set_ids (K,))`` found so far (exploration sweeps,
        then the equality pass if one ran) but those their lattice's trimming
        withdraws, then, with ``lattice_sets``, the sets the lattice implies
        (``lattice_sets.lattice_equalities``), numbered after them: for
        ``core.regularize``."""
        pairs, set_ids = found = self._found_sets()
        keep = ~self._withdrawn(found)
        implied, implied_ids = self._implied_after(found)
        return np.concatenate([pairs[keep], implied]), np.concatenate([set_ids[keep], implied_ids])

    def implied_rows(self) -> np.ndarray:
        """Rows ``(set id, from, to)`` of the lattice's sets as ``equality_sets``
        numbers them: what the graph's agent publishes at the end of its run."""
        implied, implied_ids = self._implied_after(self._found_sets())
        return np.column_stack([implied_ids, implied]).astype(np.int64)

    def withdrawn_rows(self) -> np.ndarray:
        """Rows ``(set id, from, to)`` of the found pairs the lattice's trimming
        withdraws: the graph's agent published them as it found them, and
        withdraws them at the end of its run."""
        pairs, set_ids = found = self._found_sets()
        gone = self._withdrawn(found)
        return np.column_stack([set_ids[gone], pairs[gone]]).astype(np.int64).reshape(-1, 3)

    def _withdrawn(self, found) -> np.ndarray:
        """``(K,)`` bool over the ``found`` pairs: those the lattice withdraws."""
        withdrawn = self.lattice_sets(found).withdrawn
        return np.zeros(len(found[0]), dtype=bool) if withdrawn is None else withdrawn

    def _implied_after(self, found):
        """The lattice's sets of the ``found`` sets, numbered after them."""
        pairs, set_ids = found
        implied = self.lattice_sets(found)
        first = int(set_ids.max()) + 1 if len(set_ids) else 0
        return implied.pairs, implied.set_ids + first

    def _found_sets(self):
        """The equality sets the agent found itself."""
        return self._sets.pairs, self._sets.set_ids

    def lattice_sets(self, found=None) -> LatticeSets:
        """The sets the lattice of the found sets (``found``, else
        ``_found_sets()``) implies, none without ``lattice_sets``; measured once
        for the sets and POVs known now."""
        found = self._found_sets() if found is None else found
        key = (self._sets.n_sets, self._sets.n_pairs, self._store.count, len(found[0]))
        cached = getattr(self, "_lattice_cache", None)
        if cached is None or cached[0] != key:
            if self.params.lattice_sets:
                implied = lattice_equalities(*found, self._store.count,
                                             self.params.lattice_support, self._vouched_places(),
                                             self._store.samples)
            else:
                implied = LatticeSets.none()
            self._lattice_cache = cached = (key, implied)
        return cached[1]

    def _vouched_places(self):
        """``(ij, placed)`` of another placement of the POVs on the lattice, or None."""
        return None
