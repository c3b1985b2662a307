"""Frontier rows ordered by the lattice the agent's equality sets imply.

Under noise a sweep misses some of its matches: a row whose partner is a
known POV may go unmatched, so it joins the frontier, and its search ends
on that known POV. Once the POVs fill most of the reach nearly every
frontier row is such a row, and the few positions left unknown wait for a
displacement that happens to point the budget's few rows at them.

The agent places its POVs on the lattice its equality sets imply
(``lattice.lattice_coordinates``; where a few wrong pairs leave none,
``lattice_sets.trimmed_lattice``), in a ``HoleMap``. A snapshot's matches
show the lattice step of the displacement; every placed row's target is
then a lattice point: one a known POV holds (the row is not searched), or
an empty one (searched first, the points with the most known neighbours
first: a hole inside what the agent knows). Rows the map does not place
come next, in the order they had. A search toward an empty point that
finds a new POV places it there. The map is measured again when POVs it
does not place have piled up (``REMEASURE_UNPLACED``), at most every
``REMEASURE_EVENTS`` changes.

Only where noise sized the tolerances and ``frontier_holes`` is set: a
noiseless sweep misses no match.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.naive.hole_map import HoleMap
from sensorispace_ros.core.naive.lattice import lattice_coordinates
from sensorispace_ros.core.naive.lattice_sets import trimmed_lattice

__all__ = ["FrontierHoles"]

REMEASURE_UNPLACED = 3      # POVs the map does not place that call for measuring it again
REMEASURE_EVENTS = 25       # but not more often than once in this many changes


class FrontierHoles:
    """Mixin of ``NaiveAgent``: needs its ``params``, ``_noisy``, ``_store``,
    ``_sets`` and ``_event``."""

    _frontier_map: HoleMap | None = None
    _frontier_measured = -REMEASURE_EVENTS     # the change the map was last measured at
    _frontier_points: dict | None = None       # row -> lattice point asked, this change

    def _frontier_holes(self) -> HoleMap | None:
        """The map of the POVs on their lattice, measured again where due
        (None: off, no noise, or no lattice yet)."""
        if not (self._noisy and self.params.frontier_holes):
            return None
        holes = self._frontier_map
        if holes is not None:
            holes.grow(self._store.count)
            if holes.unplaced < REMEASURE_UNPLACED:
                return holes
        if self._event - self._frontier_measured < REMEASURE_EVENTS or not len(self._sets.pairs):
            return holes
        self._frontier_measured = self._event
        pairs, set_ids, count = self._sets.pairs, self._sets.set_ids, self._store.count
        lattice = lattice_coordinates(pairs, set_ids, count)
        if lattice is None:
            lattice, _ = trimmed_lattice(pairs, set_ids, count)
        if lattice is not None:
            self._frontier_map = HoleMap(lattice, self._sets.n_sets)
        return self._frontier_map

    def _hole_order(self, order: np.ndarray, rows: np.ndarray, matched) -> np.ndarray:
        """``order`` (indices into ``rows``, a snapshot's unmatched rows) with
        the rows whose targets are empty lattice points first (most known
        neighbours first), then the rows the map does not place; the rows
        whose target a known POV holds left out (module docstring).
        ``matched``: the snapshot's matches ``(before, after)``."""
        self._frontier_points = {}
        holes = self._frontier_holes()
        before, after = (np.asarray(m, dtype=int) for m in matched)
        step = holes.displacement(before, after) if holes is not None and len(before) else None
        if step is None:
            return order
        points, known, neighbours = holes.row_targets(rows[order], step)
        placed = neighbours >= 0
        rank = np.lexsort((-neighbours, np.where(placed, 0, 1)))
        rank = rank[~known[rank]]
        self._frontier_points = {int(rows[order[i]]): tuple(points[i]) for i in rank
                                 if placed[i]}
        return order[rank]

    def _place_frontier_finds(self, requests, found, new_povs) -> None:
        """Place the new POVs this change's frontier searches found at the
        empty points their rows asked for."""
        points, holes = self._frontier_points, self._frontier_map
        if not points or holes is None:
            return
        for i, request in enumerate(requests):
            point = points.get(request.row) if request.row >= 0 else None
            if point is not None and i in found and found[i][0] in new_povs:
                holes.place(int(found[i][0]), point)
        self._frontier_points = {}
