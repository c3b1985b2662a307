"""Simulation 2 of an agent on a clock (``ClockedAgent.begin_equality_pass``).

The world replays its schedule; the agent is told nothing of when it
changes and sweeps known POVs after each change it detects. A sweep is
matched with every earlier one, not only the previous: a world the agent
met before is a displacement it can still tell, however many changes it
missed in between. A sweep senses every known POV, or a bounded, seeded
sample of them (``budget``). Its matches are rank-tested only where a set
needs them, once each, with the sweep's own row as the stencil's base.

The sets of changes imply sets of segments (``translated_sets``): a
displacement that carries ``j`` to ``j'`` and ``k`` to ``k'`` keeps the
length of ``j k``. Those make the regularisation converge with a few dozen
sweeps where the sets of changes alone need hundreds (docs/clock.md).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sensorispace_ros.core.naive.equality_sets import (RANK_DEFICIENT, RANK_FULL, RANK_UNKNOWN,
    EqualitySetSweep, check_pose_rank, finite_rows, match_sensations)
from sensorispace_ros.core.naive.jacobians import AveragedStep, CloudStep


class AllPairsSweep(EqualitySetSweep):
    """Simulation 2 that matches each sweep with every earlier one, not
    only the previous: a world the agent met before is a displacement it can
    still tell, however many changes it missed in between (``history``:
    each sweep's POV indices, sensations and ranks). With a ``budget`` a
    sweep senses that many known POVs, a seeded sample drawn afresh each
    change (``stream``: ``CounterStream``, keyed by the sweep's number), not
    every one: its cost does not grow with the POVs known, and the pairs of
    sweeps still share POVs the matches and equality sets need."""

    budget = 0
    stream = None
    tested = 0          # states rank-tested

    def _chosen(self) -> np.ndarray:
        count = len(self.probe_states)
        if self.budget <= 0 or count <= self.budget or self.stream is None:
            return np.arange(count)
        draw = self.stream.at(len(self.history))
        return np.sort(draw.choice(count, size=self.budget, replace=False))

    def observe(self) -> np.ndarray:
        chosen = self._chosen()
        current = np.asarray(self.body.sense(self.probe_states[chosen]), dtype=float)
        self.rows += len(current)
        self.calls += 1
        rank = np.full(len(current), RANK_UNKNOWN)
        tree = cKDTree(finite_rows(current, -1.0))
        matched = []
        for ids, previous, previous_rank in self.history:
            before, after = match_sensations(previous, current, match_tol=self.match_tol,
                                             separation=self.separation, tree=tree,
                                             ratio=self.ratio)
            matched.append((before, after))
            carried = (rank[after] == RANK_UNKNOWN) & (previous_rank[before] != RANK_UNKNOWN)
            rank[after[carried]] = previous_rank[before[carried]]
        self._test(chosen, current, rank, matched)
        for (ids, _, previous_rank), (before, after) in zip(self.history, matched):
            unknown = previous_rank[before] == RANK_UNKNOWN
            previous_rank[before[unknown]] = rank[after[unknown]]
            good = rank[after] == RANK_FULL
            self.sets.add(ids[before[good]], chosen[after[good]])
        self.history.append((chosen, current, rank))
        return np.zeros((0, 2), dtype=int)

    def _test(self, chosen: np.ndarray, current: np.ndarray, rank: np.ndarray,
              matched: list) -> None:
        """Rank-test, in one call, the rows of this sweep that every earlier
        sweep left unknown (all matches are gathered first: a rank one
        earlier sweep carries spares the test another would ask) and that
        can make a set: one with ``sets.min_pairs`` matches of other POVs
        not known to be rank deficient. Fills ``rank`` in place."""
        needed = []
        for (ids, _, _), (before, after) in zip(self.history, matched):
            useful = (ids[before] != chosen[after]) & (rank[after] != RANK_DEFICIENT)
            if np.count_nonzero(useful) >= self.sets.min_pairs:
                needed.append(after[useful])
        unknown = np.unique(np.concatenate(needed)) if needed else np.zeros(0, dtype=int)
        unknown = unknown[rank[unknown] == RANK_UNKNOWN]
        if len(unknown):
            full, rows = swept_rank(self, self.probe_states[chosen[unknown]], current[unknown])
            self.rows += rows
            self.calls += 1
            self.tested += len(unknown)
            rank[unknown] = np.where(full, RANK_FULL, RANK_DEFICIENT)


def swept_rank(sweep, states: np.ndarray, sensed: np.ndarray):
    """``check_pose_rank`` at ``states`` whose sensations ``sensed`` this
    sweep has just sensed in this world: the stencil's first row is the
    state itself, so only its displaced rows are sensed (``M`` rows a state
    instead of ``M + 1``). A step whose stencil senses the state more than
    once (``AveragedStep``, ``CloudStep``) senses its whole stencil. Returns
    ``(full_rank (B,) bool, rows)``."""
    step = sweep.fd_step
    base = None if isinstance(step, (AveragedStep, CloudStep)) else sensed
    return check_pose_rank(sweep.body, states, rank=sweep.rank, fd_step=step,
                           rank_ratio=sweep.rank_ratio, min_singular=sweep.min_singular,
                           pattern_ratio=sweep.pattern_ratio, sensed=base)


def translated_sets(pairs: np.ndarray, set_ids: np.ndarray, n_povs: int, per_set: int, *,
                    stream):
    """Equality sets of segments between POVs, inferred from the sets of changes.

    The changes ``j_k -> j_k'`` of one set all compensate one displacement
    ``g`` of the world: ``j_k'`` sees the moved world as ``j_k`` saw it, so
    ``j_k' = g j_k`` for every ``k``. A displacement keeps lengths, so the
    segment between two of its POVs ``j_k j_l`` and its image ``j_k' j_l'``
    have one length. Each set of ``n`` changes relates ``n (n - 1) / 2``
    segments to their images (of ``per_set`` of its changes at most, a
    seeded sample of ``stream`` keyed by the set's id: the cost stays
    ``per_set^2`` a set); segments related through any chain of sets have
    one length, and each such class of two or more segments is one more
    set. A segment is oriented so that the images of one class carry it from
    ``j_k`` to ``j_l`` (to ``j_l - j_k`` under a translation). Returns
    ``(pairs (K, 2), set_ids (K,))``, set ids from 0."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    set_ids = np.asarray(set_ids, dtype=np.int64).reshape(-1)
    starts, ends = [], []
    for set_id in np.unique(set_ids):
        changes = pairs[set_ids == set_id]
        if len(changes) > per_set:
            draw = stream.at(int(set_id))
            changes = changes[np.sort(draw.choice(len(changes), size=per_set, replace=False))]
        k, l = np.triu_indices(len(changes), 1)
        keep = (changes[k, 0] != changes[l, 0]) & (changes[k, 1] != changes[l, 1])
        starts.append(changes[k[keep], 0] * n_povs + changes[l[keep], 0])
        ends.append(changes[k[keep], 1] * n_povs + changes[l[keep], 1])
    if not starts or not sum(len(s) for s in starts):
        return np.zeros((0, 2), dtype=int), np.zeros(0, dtype=int)
    return _segment_classes(np.concatenate(starts), np.concatenate(ends), n_povs)


def _segment_classes(start: np.ndarray, end: np.ndarray, n_povs: int):
    """Classes of segments ``a * n_povs + b`` (from ``a`` to ``b``) linked
    by ``start[e] -> end[e]`` (the image of a segment under a displacement),
    oriented along the links (``translated_sets``). Returns ``(pairs, set_ids)``
    of the classes of two or more."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components

    def unordered(segment):
        a, b = np.divmod(segment, n_povs)
        return np.minimum(a, b) * n_povs + np.maximum(a, b), np.where(a < b, 1, -1)

    (start, start_sign), (end, end_sign) = unordered(start), unordered(end)
    keys, index = np.unique(np.concatenate([start, end]), return_inverse=True)
    count, edges = len(keys), len(start)
    tail, head = index[:edges], index[edges:]
    # The sign of an edge: does the image keep the segment's (low -> high) direction?
    sign = coo_matrix((start_sign * end_sign, (tail, head)), shape=(count + 1, count + 1)).tocsr()
    sign = sign + sign.T
    _, component = connected_components(sign[:count, :count], directed=False)
    first = np.unique(component, return_index=True)[1]
    # A root linked to one segment of each class; orientations follow a BFS tree.
    root = coo_matrix((np.ones(len(first)), (np.full(len(first), count), first)),
                      shape=(count + 1, count + 1))
    order, parent = breadth_first_order(sign + root + root.T, count, directed=False)
    orient = _orientations(sign, order[1:], parent, count)
    low, high = np.divmod(keys, n_povs)
    flip = orient[:count] < 0
    oriented = np.stack([np.where(flip, high, low), np.where(flip, low, high)], axis=1)
    sizes = np.bincount(component)
    kept = sizes[component] >= 2
    _, ids = np.unique(component[kept], return_inverse=True)
    return oriented[kept].astype(int), ids.reshape(-1).astype(int)


def _orientations(sign, order: np.ndarray, parent: np.ndarray, root: int) -> np.ndarray:
    """``(root + 1,)`` +1/-1 per node: a child of ``root`` +1, any other the
    orientation of its parent times the sign of their edge (>= 0: +1), the
    nodes taken in ``order`` (a BFS order, a parent before its children)."""
    linked = parent[order] != root
    nodes, parents = order[linked], parent[order[linked]]
    step = np.where(np.asarray(sign[parents, nodes]).reshape(-1) >= 0, 1, -1).tolist()
    orient = [1] * (root + 1)
    for node, up, s in zip(nodes.tolist(), parents.tolist(), step):
        orient[node] = orient[up] * s
    return np.asarray(orient, dtype=int)
