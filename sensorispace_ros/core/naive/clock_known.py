"""What the known POVs near a motor state sense now, for the agent in a world
that does not wait for it (``ClockedAgent``).

Its bounded sweep leaves most known POVs unsensed in a reaction. Before the
agent searches or walks toward a state, it senses the ``NEAR_POVS`` known POVs
nearest it in motor space: a target one of them senses is that POV, and
is neither searched nor walked again. A few rows instead of a search or a
walk, and no second POV of one position.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.naive.equality_sets import finite_rows
from sensorispace_ros.core.naive.neighbours import curve_distances
from sensorispace_ros.core.naive.points_of_view import torus_phases, torus_tree

__all__ = ["KnownNearby", "NEAR_POVS"]

NEAR_POVS = 3        # known POVs sensed per search solution to tell a duplicate


class KnownNearby:
    """Mixin of ``ClockedAgent``: needs its ``_store``, ``_body``, ``_tol``
    and ``structure``."""

    def _pending_known(self, state: np.ndarray) -> bool:
        """Does the pending solution ``state`` sense now what one of the
        ``NEAR_POVS`` known POVs nearest it in motor space senses (the sweep's
        match tolerance)? Then it is that POV, walked since its walk was cut
        (the reaction made again, or an earlier pending solution)."""
        ids = self._nearest_povs(state[None], np.arange(self._store.count))
        self._body.stage = "sweep"
        sensed = self._body.sense(np.vstack([state[None], self._store.samples[ids, 0]]))
        here, known = sensed[0], finite_rows(sensed[1:], -1.0)
        # Fewer receptors lit than the pose rank do not pin the pose (blank says nothing).
        if not len(ids) or not np.all(np.isfinite(here)) or \
                np.count_nonzero(np.abs(here) > self._tol.match) < self.structure.pose_rank:
            return False
        return bool(np.min(np.linalg.norm(known - here, axis=1)) <= self._tol.match)

    def _unswept_targets(self, requests, current) -> list:
        """The requests worth a search: a frontier row's target may be a known POV
        the bounded sweep left out, near its start (the matched neighbour's partner):
        the ``NEAR_POVS`` known POVs nearest each start are sensed first (``_sense_near``),
        and a target one of them senses is that POV, not searched (as a swept match)."""
        starts = [r.start for r in requests if r.row >= 0 and r.start is not None]
        if not starts:
            return list(range(len(requests)))
        self._sense_near(current, np.stack(starts))
        same = self._tol.match if self._tol.ratio == 0 else min(self._tol.match,
                                                                self._tol.separation)
        known = current[np.all(np.isfinite(current), axis=1)]
        return [i for i, r in enumerate(requests) if r.row < 0 or not len(known) or
                np.min(np.linalg.norm(known - r.target, axis=1)) > same]

    def _sense_near(self, current: np.ndarray, states: np.ndarray) -> None:
        """Fill the rows of ``current`` not sensed in this reaction of the ``NEAR_POVS``
        known POVs nearest (in phases, on the torus) to each of ``states``."""
        unknown = np.flatnonzero(~np.all(np.isfinite(current), axis=1))
        if not len(unknown):
            return
        ids = self._nearest_povs(states, unknown)
        self._body.stage = "sweep"
        current[ids] = self._body.sense(self._store.samples[ids, 0])
        self._body.stage = "compensation"

    def _nearest_povs(self, states: np.ndarray, among: np.ndarray) -> np.ndarray:
        """The ``NEAR_POVS`` POVs of ``among`` nearest (in phases, on the
        torus: the nearest of their samples) to each of ``states``, sorted."""
        among = np.asarray(among, dtype=int)
        if len(among) <= NEAR_POVS:
            return np.unique(among)
        allowed = np.zeros(self._store.count, dtype=bool)
        allowed[among] = True
        near = self._near_povs()
        wanted = set()
        for state in states:
            wanted.update(near.nearest(state, allowed, NEAR_POVS).tolist())
        return np.asarray(sorted(wanted), dtype=int)

    def _near_povs(self) -> "NearestPovs":
        """The ``NearestPovs`` of the POVs known now: kept across reactions
        (not in a checkpoint), rebuilt when the POVs it holds are no longer
        the first ones known (an undo dropped them) or grew by an eighth."""
        near = getattr(self, "_nearest_cache", None)
        if near is None or not near.holds(self._store):
            near = self._nearest_cache = NearestPovs(self._store)
        return near.extended(self._store)


class NearestPovs:
    """A tree over the samples of the first ``built`` POVs of a store (torus
    of phases) and the store's later POVs, measured one by one: the POVs
    nearest a state by their nearest sample, exactly."""

    def __init__(self, store):
        samples = store.samples
        self.built = len(samples)
        self.n_samples = samples.shape[1]
        self._first = samples[:, 0].copy()     # the POVs it holds, to tell a store that dropped them
        self._tree = torus_tree(samples.reshape(-1, samples.shape[2])) if self.built else None
        self._later = samples[:0]

    def __getstate__(self):
        return {"built": -1}        # pickled (a restart's snapshot) without its tree: rebuilt

    def holds(self, store) -> bool:
        """Are this tree's POVs the store's first ones, and not an eighth fewer than it holds?"""
        count = store.count
        if self.built < 0:
            return False
        return count >= self.built and count <= self.built * 9 / 8 + 8 and \
            np.array_equal(store.samples[:self.built, 0], self._first)

    def extended(self, store) -> "NearestPovs":
        self._later = store.samples[self.built:]
        return self

    def nearest(self, state: np.ndarray, allowed: np.ndarray, k: int) -> np.ndarray:
        """The ``k`` POVs with ``allowed`` (``(P,)`` bools) nearest ``state``,
        nearest first (fewer when fewer are allowed)."""
        ids, reach = [], []
        if len(self._later):
            later = self.built + np.arange(len(self._later))
            keep = allowed[later]
            ids.append(later[keep])
            reach.append(curve_distances(state, self._later[keep]))
        if self._tree is not None:
            seen, distance = self._tree_nearest(state, allowed[:self.built], k)
            ids.append(seen)
            reach.append(distance)
        ids, reach = np.concatenate(ids), np.concatenate(reach)
        return ids[np.argsort(reach, kind="stable")[:k]]

    def _tree_nearest(self, state, allowed, k):
        """The allowed POVs of the tree met among ``state``'s nearest samples
        and their distances (each its nearest sample's), at least ``k`` of
        them (or every allowed one): a POV not met lies farther than all."""
        total = self.built * self.n_samples
        asked = min(total, 4 * self.n_samples)
        point = torus_phases(np.asarray(state, dtype=float))
        while True:
            distance, index = self._tree.query(point, k=asked)
            owner = np.atleast_1d(index) // self.n_samples
            distance = np.atleast_1d(distance)
            owner, first = np.unique(owner, return_index=True)
            met = allowed[owner]
            if met.sum() >= k or asked == total:
                return owner[met], distance[first][met]
            asked = min(total, 2 * asked)
