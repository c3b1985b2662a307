"""Which frontier rows the naive agent searches, and how many.

A frontier row is a row of the most recent confirmed snapshot that no known
POV matches now (``anchors.frontier_requests``): its target is the pose
next to the known ones that the object's displacement moved it to, which
may be a new POV, a pose whose POV splits, or a pose no motor state reaches.
The agent searches ``_frontier_budget`` of them per event, fewer while they
keep failing (``_track_frontier``).

With ``frontier_skip_split`` or ``frontier_give_way``, where noise sized the
tolerances, the budget is kept on targets that may still be new POVs
(``_frontier_order``):

* a row whose target a remembered split POV senses now, within what two
  sensings of one pose differ by, is not searched: a search would end on
  that loop, walked before and found split. The next rows fill the budget;

and with ``frontier_give_way`` the rows are also taken in this order:

* the rows whose searches failed least often come first (``frontier_fails``,
  counted per POV: its row searched and no new POV found), then the nearest
  in sensation to a matched row. A row whose targets keep failing (one at
  the edge of what the arm reaches, whose displaced targets fall beyond it
  or into the split poses) gives its turn to the others, so the POVs next
  to a region not yet explored are searched too, however often the budget
  is one.

Where the agent averages its targets (``targets.averages_targets``), the rows
of most sensings come first, then the nearest. Otherwise the order is the
nearest in sensation first; a search's end on a
remembered split POV is found after the search (``searching._known_solutions``).
The order trades coverage between seeds (docs/mujoco.md, "Frontier rows
that keep failing give way"), hence off by default; skipping the split rows
alone is set where it was measured (``config/mujoco-ring.yaml``).
"""
from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from .frontier_holes import FrontierHoles
from .targets import averages_targets


class FrontierChoice(FrontierHoles):
    """Mixin of ``NaiveAgent``: needs its ``params``, ``structure``, ``_body``,
    ``_store``, ``_pool``, ``_sets``, ``_event``, ``_noisy`` and
    ``_frontier_success``; reads the sensations of the remembered split POVs
    this event (``_split_now``)."""

    def _frontier_order(self, distance, rows, snapshot, matched=None) -> np.ndarray:
        """Indices into ``rows`` (a snapshot's unmatched rows, ``distance``
        their sensory distance to the nearest matched row), in the order
        their requests are made (module docstring); the split ones left out.
        Given the snapshot's matches ``matched`` ``(before, after)``, then
        ordered by the lattice (``frontier_holes``)."""
        order = self._rows_in_turn(distance, rows, snapshot)
        return order if matched is None else self._hole_order(order, rows, matched)

    def _rows_in_turn(self, distance, rows, snapshot) -> np.ndarray:
        """``_frontier_order`` before the lattice's order."""
        order = np.argsort(distance, kind="stable")
        if snapshot.counts is not None and averages_targets(self):
            order = order[np.argsort(-snapshot.counts[rows[order]], kind="stable")]
        if self._skips_split():
            order = order[~self._split_sensed(rows, snapshot)[order]]
        if not self._give_way():
            return order
        fails = self._frontier_fails()
        return order[np.argsort(fails[rows[order]], kind="stable")]

    def _split_sensed(self, rows, snapshot) -> np.ndarray:
        """``(len(rows),)`` whether a remembered split POV senses the row's target
        now, within what two sensings of one pose differ by (``_split_now``)."""
        split = np.asarray(getattr(self, "_split_now", ()), dtype=float)
        if not split.size:
            return np.zeros(len(rows), dtype=bool)
        sd2 = self.structure.noise ** 2
        quantile = chi2.ppf(self.params.noise_confidence, self._body.n_sensors)
        counts = np.array([snapshot.count(int(r)) for r in rows], dtype=float)
        return _sensed_by_any(snapshot.sensations[rows], split,
                              quantile * sd2 * (1.0 + 1.0 / counts))

    def _give_way(self) -> bool:
        """Whether the order of ``frontier_give_way`` applies (noise sized the tolerances)."""
        return bool(self._noisy and self.params.frontier_give_way)

    def _skips_split(self) -> bool:
        """Whether rows a remembered split POV senses are passed over
        (``frontier_skip_split`` or ``frontier_give_way``, where noise sized the tolerances)."""
        return bool(self._noisy and (self.params.frontier_skip_split
                                     or self.params.frontier_give_way))

    def _frontier_fails(self) -> np.ndarray:
        """``(P,)`` frontier searches of each known POV's row that found no new POV."""
        fails = getattr(self, "_fails", np.zeros(0, dtype=int))
        if len(fails) < self._store.count:
            fails = np.concatenate([fails, np.zeros(self._store.count - len(fails), dtype=int)])
            self._fails = fails
        return fails

    def _track_frontier(self, requests, found, new_povs) -> None:
        """Moving average of the frontier searches (``requests`` searched) that
        found a new POV; under noise, each row's failures (``_frontier_fails``)."""
        frontier = [i for i, r in enumerate(requests) if r.row >= 0]
        hit = [i in found and found[i][0] >= 0 and found[i][0] in new_povs for i in frontier]
        if self._give_way():
            fails = self._frontier_fails()
            for i, new in zip(frontier, hit):
                fails[requests[i].row] += not new
        self._place_frontier_finds(requests, found, new_povs)
        if frontier:
            self._frontier_success = 0.9 * self._frontier_success + 0.1 * sum(hit) / len(frontier)

    def _frontier_budget(self) -> int:
        """Frontier searches this event: ``frontier_attempts`` while they
        find new POVs, down to one when they keep failing (the known POVs
        already fill the reachable region; later translations may still
        uncover a corner, so the agent keeps trying once per event)."""
        share = min(1.0, self._frontier_success / 0.2)
        return max(1, int(np.ceil(self.params.frontier_attempts * share)))


def _sensed_by_any(targets: np.ndarray, sensed: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """``(R,)`` whether a row of ``sensed`` (non-finite rows never) lies within
    squared distance ``limit[r]`` of ``targets[r]``."""
    result = np.zeros(len(targets), dtype=bool)
    for r, target in enumerate(targets):
        with np.errstate(invalid="ignore"):
            d2 = np.sum((sensed - target) ** 2, axis=1)
        result[r] = bool(np.any(d2 <= limit[r]))
    return result
