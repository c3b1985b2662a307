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
        wanted = set()
        for state in states:
            wanted.update(self._store.nearest(state, allowed, NEAR_POVS).tolist())
        return np.asarray(sorted(wanted), dtype=int)
