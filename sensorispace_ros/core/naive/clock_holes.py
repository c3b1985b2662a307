"""Searches toward the holes of what the agent knows, for the agent in a
world that does not wait for it (``ClockedAgent``).

A confirmed snapshot's rows that match nothing now are the frontier: their
targets are positions the object's displacement moved known ones to. Once
the POVs fill most of the reach, nearly all those targets are known POVs
the bounded sweep did not sense, or poses past the reach: frontier searches
end on a known POV or fail, reaction after reaction, while the few
positions left unknown wait for a displacement that happens to point a
searched row at them.

With ``clock_hole_targets`` the agent places its POVs on the lattice its
equality sets imply (``lattice``, ``hole_map``) as soon as they imply one.
Each snapshot a match confirmed then says, for every row, which lattice
point its target lies at: a known POV's, not searched, or an empty one. The
agent searches up to ``frontier_attempts`` empty points, those with the
most known neighbours first (a hole inside what it knows), each from the
known POV next to it, and gives a point up after ``clock_hole_attempts``
searches that found no new POV there. Until the sets imply a lattice, and
from when a set contradicts it (under noise, a wrong match), the frontier
rows are searched as before.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.naive.anchors import Request
from sensorispace_ros.core.naive.equality_sets import RANK_DEFICIENT
from sensorispace_ros.core.naive.hole_map import HoleMap
from sensorispace_ros.core.naive.lattice import lattice_coordinates

__all__ = ["HoleTargets"]

REMEASURE_UNPLACED = 3      # unplaced POVs that call for measuring the lattice again
REMEASURE_SETS = 200        # so do this many equality sets added since
REMEASURE_EVENTS = 25       # but not more often than once in this many events


class HoleTargets:
    """Mixin of ``ClockedAgent``: needs its ``params``, ``_store``, ``_sets``,
    ``_pool`` and ``_event``."""

    _hole_map: HoleMap | None = None
    _hole_tried = -REMEASURE_EVENTS      # the event the lattice was last measured at
    _hole_points: dict | None = None     # request index -> lattice point, this reaction

    def _holes_now(self) -> HoleMap | None:
        """The hole map, the lattice measured again where it is due (None:
        no lattice yet, or ``clock_hole_targets`` off)."""
        if not self.params.clock_hole_targets:
            return None
        holes = self._hole_map
        if holes is not None:
            holes.grow(self._store.count)
            current = holes.unplaced < REMEASURE_UNPLACED and \
                self._sets.n_sets - holes.n_sets < REMEASURE_SETS
            if current:
                return holes
        if self._event - self._hole_tried < REMEASURE_EVENTS:
            return holes
        self._hole_tried = self._event
        pairs, set_ids = self._sets.pairs, self._sets.set_ids
        lattice = lattice_coordinates(pairs, set_ids, self._store.count)
        if lattice is None:
            # Sets that no longer imply a lattice may still agree with the map
            # (POVs tied too loosely yet); a set the map contradicts ends it.
            if holes is not None and holes.contradicted(pairs, set_ids):
                self._hole_map = None
            return self._hole_map
        n_sets = self._sets.n_sets
        self._hole_map = HoleMap(lattice, n_sets) if holes is None else \
            holes.remeasured(lattice, n_sets)
        return self._hole_map

    def _vouched_places(self):
        """Where the hole map places the POVs (``ImpliedSets``): the searches
        toward its empty points place the POVs they found, set or no set."""
        holes = self._hole_map
        return None if holes is None else (holes.ij, holes.placed)

    def _hole_requests(self, matches, requests: list) -> list:
        """``requests`` with their frontier rows replaced by searches toward
        the holes the confirmed snapshots point at (module docstring); as
        they are where there is no lattice. Notes the requested points."""
        self._hole_points = {}
        holes = self._holes_now()
        if holes is None:
            return requests
        targets = []
        for k, (before, after) in enumerate(matches):
            step = holes.displacement(before, after) if len(before) else None
            if step is None:
                continue
            snap = self._pool[k]
            rows = np.flatnonzero(np.all(np.isfinite(snap.sensations), axis=1)
                                  & (snap.rank != RANK_DEFICIENT))
            rows = np.setdiff1d(rows, before)
            targets.append((k, rows[rows != snap.rest_pov], step))
        chosen = holes.candidates(targets, self.params.clock_hole_attempts)
        anchors = [r for r in requests if r.row < 0]
        samples = self._store.samples
        for c in chosen[:self.params.frontier_attempts]:
            snap = self._pool[c.snapshot]
            self._hole_points[len(anchors)] = c.point
            anchors.append(Request(c.snapshot, c.row, snap.sensations[c.row],
                                   samples[c.row, 0], samples[c.neighbour, 0],
                                   snap.count(c.row)))
        return anchors

    def _track_holes(self, found: dict, new_povs) -> None:
        """Place the POVs this reaction's hole searches found; count the
        others as failures of their points."""
        holes = self._hole_map
        if holes is None or not self._hole_points:
            return
        for i, point in self._hole_points.items():
            pov = found[i][0] if i in found else -1
            if pov >= 0 and pov in new_povs:
                holes.place(pov, point)
            else:
                holes.failed(point)
        self._hole_points = {}
